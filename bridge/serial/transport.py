"""Framed robot messages over a serial port: the host's end of a link
(sim_backend/link.py HostEnd).

One SerialTransport per port. A port is a device path (`/dev/ttyUSB0`), our
own URL `serial:///dev/ttyUSB0?baud=115200`, or any pyserial URL
(`loop://`, `socket://127.0.0.1:7777`, `rfc2217://...`, `spy://...`).

Every frame is COBS + CRC-16 (firmware_logic/framing.py). Bytes that do not
form a valid frame are dropped up to the next delimiter and counted by fault
(`bad_frames()`); each fault kind is logged once. Every read has a timeout.
A port that disappears (USB unplugged, pty closed) is counted as
`disconnect`, and reopened on later polls every `reopen_every` seconds until
it comes back; while it is gone, polls wait out their timeout and return
nothing, and sends are dropped (counted as `send_dropped`): the robots
retransmit unacknowledged touches and the coordinator re-sends commands, so
nothing acknowledged is lost.

Bytes outside a run of frames are the board's REPL, not bad frames: on every
(re)open and after a board's ACTION STOP (the last frame of its run,
firmware_logic/board.py) the decoder hunts for the next valid frame
(framing.Decoder.hunt) and counts what it passes over in `skipped`. Frames
for a board that has stopped are not sent (`sends_after_stop`): its REPL
would read them as keystrokes (Ctrl-A, Ctrl-D run or reset) until the board
is heard again.
"""

from __future__ import annotations

import logging
import time
from types import TracebackType
from urllib.parse import parse_qs, urlsplit

import serial

from bridge.serial.errors import SerialOpenError
from bridge.transport import FanIn, Message
from firmware_logic import board, framing
from firmware_logic import messages as msg

log = logging.getLogger(__name__)


DEFAULT_BAUD = 115200


def resolve_url(url: str, scheme: str = "serial", default_baud: int = DEFAULT_BAUD,
                options: tuple[str, ...] = ("baud",)) -> tuple[str, dict[str, str]]:
    """Split `SCHEME:///dev/x?baud=N` into a pyserial port and its options.

    Device paths and pyserial URLs (loop://, socket://, rfc2217://, ...) pass
    through unchanged with no options. Unknown options raise SerialOpenError
    naming the expected form.
    """
    prefix = scheme + "://"
    if not url.startswith(prefix):
        return url, {}
    parts = urlsplit(url)
    port = parts.path or parts.netloc
    if not port:
        raise SerialOpenError("%r names no port; expected %s:///dev/ttyUSB0?baud=%d"
                              % (url, scheme, default_baud))
    opts: dict[str, str] = {}
    for key, values in parse_qs(parts.query, keep_blank_values=True).items():
        if key not in options:
            raise SerialOpenError("unknown option %r in %r; expected %s:///dev/ttyUSB0?%s"
                                  % (key, url, scheme,
                                     "&".join("%s=..." % o for o in options)))
        opts[key] = values[-1]
    if "baud" in opts:
        try:
            int(opts["baud"])
        except ValueError:
            raise SerialOpenError("baud=%r in %r is not a number; expected e.g. baud=%d"
                                  % (opts["baud"], url, default_baud)) from None
    return port, opts


def open_serial(port: str, baud: int, timeout: float, **kw: object) -> serial.SerialBase:
    """serial_for_url with a read and a write timeout, errors as SerialOpenError."""
    try:
        return serial.serial_for_url(port, baudrate=baud, timeout=timeout,
                                     write_timeout=max(timeout, 0.5), **kw)
    except (serial.SerialException, OSError, ValueError) as err:
        raise SerialOpenError("cannot open serial port %r at %d baud: %s" % (port, baud, err)) \
            from err


class SerialTransport:
    """The host's end of a link over one serial port carrying framed messages."""

    def __init__(self, url: str, baud: int | None = None, timeout: float = 0.05,
                 reopen_every: float = 0.2) -> None:
        port, opts = resolve_url(url)
        self.url = url
        self.port = port
        self.baud = int(opts.get("baud", baud or DEFAULT_BAUD))
        self.timeout = timeout
        self.reopen_every = reopen_every
        self._dec = framing.Decoder()
        self._enc = framing.Encoder()
        self._faults: dict[str, int] = {}
        self._logged: set[str] = set()
        self._next_reopen = 0.0
        self.nodes: set[int] = set()          # robot nodes heard on this port
        self.stopped: set[int] = set()        # nodes whose last frame was ACTION STOP
        self.frames_in = 0
        self.frames_out = 0
        self.sends_after_stop = 0
        self._skipped_logged = 0              # dec.skipped when last logged
        self._closed = False
        self._ser: serial.SerialBase | None = open_serial(port, self.baud, timeout)
        self._dec.hunt()      # joined mid-line: e.g. the REPL's output deploy --start left

    # -- context manager ---------------------------------------------------------

    def __enter__(self) -> "SerialTransport":
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def close(self) -> None:
        self._closed = True
        self._drop_port()

    def _drop_port(self) -> None:
        """Forget the port, closing it quietly: it may already be gone."""
        ser, self._ser = self._ser, None
        if ser is not None:
            try:
                ser.close()
            except (serial.SerialException, OSError):
                pass

    # -- faults ------------------------------------------------------------------

    def _fault(self, kind: str, detail: str = "", n: int = 1) -> None:
        self._faults[kind] = self._faults.get(kind, 0) + n
        if kind not in self._logged:
            self._logged.add(kind)
            log.warning("%s: %s%s (logged once; see bad_frames())", self.url, kind,
                        ": " + detail if detail else "")

    def bad_frames(self) -> dict[str, int]:
        out = dict(self._faults)
        for k, v in self._dec.error_counts().items():
            out[k] = out.get(k, 0) + v
        return out

    def _sync_decoder_faults(self, before: list[int]) -> None:
        for i, name in enumerate(framing.ERR_NAMES):
            if self._dec.errors[i] != before[i] and name not in self._logged:
                self._logged.add(name)
                log.warning("%s: bad frame (%s), dropped; resynchronising on the next "
                            "delimiter (logged once; see bad_frames())", self.url, name)

    # -- the port coming and going -------------------------------------------------------

    @property
    def skipped(self) -> int:
        """Bytes passed over outside a run of frames (before the first frame
        after an open, after a board's STOP): never bad frames."""
        return self._dec.skipped

    @property
    def connected(self) -> bool:
        return self._ser is not None

    def _lost(self, err: BaseException) -> None:
        self._fault("disconnect", str(err))
        self._drop_port()
        self._dec.hunt()
        self._next_reopen = time.monotonic() + self.reopen_every

    def _reopen(self) -> bool:
        if self._closed:
            return False
        now = time.monotonic()
        if now < self._next_reopen:
            return False
        self._next_reopen = now + self.reopen_every
        try:
            self._ser = open_serial(self.port, self.baud, self.timeout)
        except SerialOpenError:
            return False
        self._dec.hunt()
        log.info("%s: port is back", self.url)
        return True

    # -- HostEnd ------------------------------------------------------------------

    def poll(self, timeout: float) -> list[Message]:
        """Messages that arrive within `timeout` seconds (returns early once
        at least one message is in and the port has nothing more waiting)."""
        if self._closed:
            raise SerialOpenError("%s: transport is closed" % self.url)
        deadline = time.monotonic() + timeout
        out: list[Message] = []
        dec = self._dec
        while True:
            remaining = deadline - time.monotonic()
            ser = self._ser
            if ser is None and not self._reopen():
                if remaining > 0:
                    time.sleep(min(remaining, self.reopen_every))
                if time.monotonic() >= deadline:
                    return out
                continue
            ser = self._ser
            assert ser is not None
            try:
                waiting = ser.in_waiting
                if waiting == 0 and out:
                    return out
                if waiting == 0 and remaining <= 0:
                    return out
                # the port's own timeout (self.timeout) bounds this read;
                # changing ser.timeout would reconfigure the port every time
                data = ser.read(max(1, waiting))
            except (serial.SerialException, OSError) as err:
                self._lost(err)
                continue
            if not data:
                if time.monotonic() >= deadline:
                    return out
                continue
            before = list(dec.errors)
            for b in data:
                if dec.feed(b):
                    if dec.skipped != self._skipped_logged:
                        self._skipped_logged = dec.skipped
                        log.info("%s: skipped %d bytes outside frames so far (a REPL's "
                                 "output before a run's first frame or after its last)",
                                 self.url, dec.skipped)
                    self.frames_in += 1
                    node = dec.node
                    if node == msg.HOST or node > msg.MAX_NODE:
                        self._fault("node", "frame from node %d" % node)
                        continue
                    self.nodes.add(node)
                    f = tuple(dec.fields[:dec.nfields])
                    if board.is_stop(dec.kind, f):
                        self.stopped.add(node)
                        dec.hunt()        # the board's REPL has the line again
                    else:
                        self.stopped.discard(node)
                    out.append((node, dec.kind, f))
            if dec.errors != before:
                self._sync_decoder_faults(before)

    def encode(self, node: int, kind: int, fields: tuple) -> bytes:
        """The framed bytes of one message (raises SchemaError on a bad field)."""
        args = list(fields) + [0] * (6 - len(fields))
        n = self._enc.frame(kind, node, args[0], args[1], args[2], args[3], args[4], args[5])
        return bytes(self._enc.out[:n])

    def send(self, node: int, kind: int, fields: tuple) -> None:
        data = self.encode(node, kind, fields)
        if node in self.stopped or (node == msg.HOST and self.nodes
                                    and self.nodes <= self.stopped):
            self.sends_after_stop += 1
            if self.sends_after_stop == 1:
                log.info("%s: not sending to node %d: its run has ended (ACTION STOP); "
                         "its REPL would read frames as keystrokes", self.url, node)
            return
        if self._ser is None and not self._reopen():
            self._fault("send_dropped", "port is gone")
            return
        ser = self._ser
        assert ser is not None
        try:
            ser.write(data)
            self.frames_out += 1
        except serial.SerialTimeoutException as err:
            self._fault("send_timeout", str(err))
        except (serial.SerialException, OSError) as err:
            self._lost(err)
            self._fault("send_dropped", "port is gone")


class MultiSerialTransport(FanIn):
    """Several serial ports as one host end (see bridge.transport.FanIn)."""

    def __init__(self, transports: list[SerialTransport]) -> None:
        super().__init__(transports)
        self.transports = self.parts

    @classmethod
    def open(cls, urls: list[str], baud: int | None = None,
             timeout: float = 0.05) -> "MultiSerialTransport":
        opened: list[SerialTransport] = []
        try:
            for u in urls:
                opened.append(SerialTransport(u, baud, timeout))
        except BaseException:
            for t in opened:
                t.close()
            raise
        return cls(opened)
