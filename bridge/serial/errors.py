"""Errors of the serial links and serial bodies (all under BridgeError)."""

from __future__ import annotations

from bridge.errors import BridgeError


class SerialLinkError(BridgeError):
    """A serial port could not be opened or used."""


class SerialOpenError(SerialLinkError):
    """Opening the port failed (missing device, bad URL or option)."""


class SerialTimeout(SerialLinkError, TimeoutError):
    """The device did not answer within the timeout."""


class ProtocolError(SerialLinkError):
    """The device answered something the protocol does not allow."""
