"""Errors of the links: one root with initialisation, operation and timeout
subclasses (the timeout one is also a TimeoutError), as python-can does."""

from __future__ import annotations

from bridge.errors import BridgeError, UsageError


class LinkError(BridgeError):
    """Base of every error a link raises."""


class LinkInitError(LinkError):
    """A bus or port could not be opened (missing driver, device, option)."""


class LinkOperationError(LinkError):
    """Sending or receiving failed on an open link."""


class LinkTimeoutError(LinkError, TimeoutError):
    """An expected frame did not arrive in time."""


class LinkURLError(LinkInitError, UsageError):
    """A link URL is malformed or has an unknown option; names the expected form."""


class KeyMismatch(LinkError):
    """Host and robots do not share a key file (one of them has none, or they
    have different ones): the robots would drop every host command."""
