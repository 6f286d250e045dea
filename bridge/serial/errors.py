"""Errors of the serial links and serial bodies (all under BridgeError).

`PORT_ERRORS` is everything pyserial and the OS raise when a port fails or
vanishes (on POSIX a dead tty makes tcflush / tcgetattr raise termios.error,
which is not an OSError). Drivers catch exactly these at the seam and raise
a typed error below instead, so callers never see a raw termios.error.
"""

from __future__ import annotations

import serial

from bridge.errors import BridgeError

try:
    import termios
    PORT_ERRORS: tuple[type[BaseException], ...] = (serial.SerialException, OSError,
                                                    termios.error)
except ImportError:                     # pragma: no cover - not POSIX
    PORT_ERRORS = (serial.SerialException, OSError)


class SerialLinkError(BridgeError):
    """A serial port could not be opened or used."""


class SerialOpenError(SerialLinkError):
    """Opening the port failed (missing device, bad URL or option)."""


class SerialTimeout(SerialLinkError, TimeoutError):
    """The device did not answer within the timeout."""


class SerialPortLost(SerialTimeout):
    """The port failed or vanished (USB unplugged, pty closed); the driver
    reopens it on its next call. A SerialTimeout because, to a caller, a
    device that is gone is one that does not answer: retry later."""


class PortClosedError(SerialLinkError):
    """The driver was used after close()."""


class ProtocolError(SerialLinkError):
    """The device answered something the protocol does not allow."""
