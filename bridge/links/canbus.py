"""python-can backends of the link registry, with errors converted at the seam."""

from __future__ import annotations

import binascii
import contextlib
import logging
import os
import select
import time
from collections import deque
from typing import Any, Iterator

import can
import serial
from can.interfaces.slcan import slcanBus

from bridge.links.errors import LinkError, LinkTimeoutError

log = logging.getLogger(__name__)

READ_CHUNK = 65536
# seconds a write to an SLCAN adapter may block before it fails (a typed
# LinkTimeoutError): an adapter that stops reading must not hang the host
WRITE_TIMEOUT = 0.25


def _why(err: BaseException) -> str:
    """The error's text plus its cause's: python-can's own messages ("Could not
    read from serial device") leave out what actually happened."""
    text = str(err) or type(err).__name__
    cause = err.__cause__
    if cause is not None and str(cause) and str(cause) not in text:
        text += f": {cause}"
    return text


@contextlib.contextmanager
def converted(what: str) -> Iterator[None]:
    """Turn python-can's and the OS's errors into the link error tree, naming
    `what` (which says whether the link could not be opened or failed in use)."""
    try:
        yield
    except LinkError:
        raise                      # already converted (e.g. a LinkTimeoutError, an OSError too)
    except TimeoutError as err:    # can.CanTimeoutError included; before OSError, its base
        raise LinkTimeoutError(f"{what}: timed out ({_why(err)})") from err
    except can.CanInterfaceNotImplementedError as err:
        raise LinkError(f"{what}: interface not available ({_why(err)})") from err
    except can.CanError as err:
        raise LinkError(f"{what}: {_why(err)}") from err
    except OSError as err:
        raise LinkError(f"{what}: {err}") from err


def shutdown_quietly(bus: Any, what: str) -> None:
    """Shut a bus down; never raise. A link that is already gone (the adapter
    unplugged, the robots' process killed) fails to close too, and that
    second error must not mask the first."""
    try:
        bus.shutdown()
    except (can.CanError, OSError, ValueError) as err:
        log.warning("%s: closing the link failed (%s); it is dropped", what, _why(err))


def _bus(what: str, cls: type[can.BusABC] | None = None, **kw: Any) -> can.BusABC:
    with converted(f"cannot open {what}"):
        try:
            return cls(**kw) if cls is not None else can.Bus(**kw)
        except ValueError as err:
            raise LinkError(f"cannot open {what}: {err}") from err


def open_virtual(channel: str) -> can.BusABC:
    return _bus(f"virtual://{channel}", interface="virtual", channel=channel,
                receive_own_messages=False)


def open_socketcan(channel: str) -> can.BusABC:
    return _bus(f"socketcan://{channel}", interface="socketcan", channel=channel)


class SlcanBus(slcanBus):
    """python-can's slcan bus with a block reader and a shutdown that never raises.

    python-can reads the port one byte per call (a select and a read per byte,
    some 45 system calls per frame), which caps an SLCAN pty below a saturated
    500 kbit/s bus on one core. This reads whatever the port holds in one call,
    splits it into lines, and parses standard data frames itself; other lines
    (extended, remote, FD) go to python-can's parser. Adapter replies (CR, z, Z,
    BEL) are consumed without ending a receive early. A line that does not parse
    raises ValueError, as python-can's parser does (the host counts it).
    """

    def __init__(self, channel: str, **kw: Any) -> None:
        self._lines: deque[bytes | bytearray] = deque()      # split off a bytearray
        self._rx = bytearray()
        self._fd: int | None = None
        super().__init__(channel, **kw)
        port = self.serialPortOrig
        # a local tty (posix pyserial, non-blocking fd): read it directly;
        # pyserial URL handlers (socket://, rfc2217://) go through pyserial
        if type(port).__module__ == "serial.serialposix" and isinstance(
                getattr(port, "fd", None), int):
            self._fd = port.fd

    # -- reading -----------------------------------------------------------------

    def _fill(self, timeout: float | None) -> bool:
        """Read what the port holds, waiting up to `timeout` for the first byte;
        False when nothing came."""
        fd = self._fd
        if fd is not None:
            # select even for a zero timeout: a raw tty (VMIN 0) reads b"" both
            # when nothing waits and when the other end hung up; only after
            # select said readable does b"" mean the adapter is gone
            if not select.select([fd], [], [], timeout)[0]:
                return False
            try:
                data = os.read(fd, READ_CHUNK)
            except (BlockingIOError, InterruptedError):
                return False
            except OSError as err:     # EIO: the other end of the pty is gone
                raise can.CanOperationError(f"Could not read from serial device: {err}") \
                    from err
            if not data:
                raise can.CanOperationError("Could not read from serial device: end of file "
                                            "(the adapter went away)")
        else:
            port = self.serialPortOrig
            with can.exceptions.error_check("Could not read from serial device"):
                # the port's own timeout (python-can's `timeout`, 1 ms) bounds this read
                data = port.read(max(1, port.in_waiting))
            if not data:
                return False
        rx = self._rx
        rx += data
        if b"\a" in data:          # an error reply (BEL) ends a line as CR does
            rx[:] = rx.replace(b"\a", b"\a\r")
        parts = rx.split(b"\r")
        rx[:] = parts.pop()
        self._lines.extend(parts)
        return True

    def _next_line(self, deadline: float | None) -> bytes | bytearray | None:
        lines = self._lines
        while not lines:
            # always one read, even with no time left: a zero timeout still
            # takes what is already waiting
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            if not self._fill(left) and deadline is not None and time.monotonic() >= deadline:
                return None
        return lines.popleft()

    def _read(self, timeout: float | None) -> str | None:
        """One adapter line with its terminator (python-can's contract; used by
        get_version and get_serial_number)."""
        deadline = None if timeout is None else time.monotonic() + timeout
        line = self._next_line(deadline)
        if line is None:
            return None
        return line.decode("latin-1") + ("" if line.endswith(b"\a") else "\r")

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            line = self._next_line(deadline)
            if line is None:
                return None, False
            kind = line[:1]
            if kind == b"t":
                dlc = line[4] - 48 if len(line) > 4 else -1
                data = binascii.unhexlify(line[5:5 + 2 * dlc]) if 0 <= dlc <= 8 else b""
                if dlc < 0 or dlc > 8 or len(data) != dlc:
                    raise ValueError(f"malformed SLCAN frame {line!r}")
                return can.Message(timestamp=time.time(), arbitration_id=int(line[1:4], 16),
                                   is_extended_id=False, dlc=dlc, data=data), False
            if kind and kind in b"TxrRdDbB":
                # python-can's parser takes queued lines first
                self._queue.put_nowait(line.decode("latin-1") + "\r")
                return super()._recv_internal(0.0)
            # an adapter reply (CR, z, Z, BEL, version): not a frame, read on

    # -- writing -----------------------------------------------------------------

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        """python-can's send, never without a write timeout (it sets the
        port's write_timeout to `timeout`, None blocking for ever)."""
        super().send(msg, WRITE_TIMEOUT if timeout is None else timeout)

    def _write(self, string: str) -> None:
        """One adapter line; CanTimeoutError when the adapter does not take it
        within the write timeout. No tcdrain (python-can's flush): it waits,
        with no timeout at all, until the adapter read everything."""
        port = self.serialPortOrig
        if port.write_timeout is None:
            port.write_timeout = WRITE_TIMEOUT
        try:
            port.write(string.encode() + self.LINE_TERMINATOR)
        except serial.SerialTimeoutException as err:
            raise can.CanTimeoutError(f"the adapter took no frame for {port.write_timeout:g} "
                                      f"s (it stopped reading)") from err
        except (serial.SerialException, OSError) as err:
            raise can.CanOperationError(f"Could not write to serial device: {err}") from err

    def flush(self) -> None:
        self._lines.clear()
        self._rx.clear()
        super().flush()

    # -- closing -------------------------------------------------------------------

    def shutdown(self) -> None:
        """Idempotent, and never raises: python-can's writes a close command
        first and raises (leaking the port) when the adapter is already gone."""
        if self._is_shutdown:
            return
        can.BusABC.shutdown(self)
        try:
            self.close()
        except can.CanError as err:
            log.debug("slcan %s: close command not sent: %s", self.channel_info, _why(err))
        try:
            self.serialPortOrig.close()
        except OSError as err:
            log.debug("slcan %s: port close failed: %s", self.channel_info, err)


def open_slcan(channel: str, bitrate: int | None = None, baud: int = 115200,
               settle_ms: int | None = None) -> can.BusABC:
    """settle_ms: wait after opening the port (python-can's default, 2 s, lets an
    Arduino-style board reset; a pty or a CANable needs 0)."""
    kw: dict[str, Any] = {"tty_baudrate": baud}
    if settle_ms is not None:
        kw["sleep_after_open"] = settle_ms / 1000.0
    if bitrate is not None:
        kw["bitrate"] = bitrate
    return _bus(f"slcan://{channel}", SlcanBus, channel=channel, **kw)


def open_interface(channel: str, bitrate: int | None = None) -> can.BusABC:
    interface, _, chan = channel.partition("/")
    if interface == "udp_multicast":
        raise LinkError("can://udp_multicast/... is not allowed: it leaves the machine; "
                        "use virtual://CHANNEL")
    kw: dict[str, Any] = {}
    if bitrate is not None:
        kw["bitrate"] = bitrate
    return _bus(f"can://{channel}", interface=interface, channel=chan, **kw)
