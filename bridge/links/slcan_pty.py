"""The face of an SLCAN adapter on a pseudo-terminal, in pure Python.

`SlcanPtyBus` is a python-can bus for the process that owns the robots: it
opens a pty, links its slave end at a path, and speaks the SLCAN (Lawicel)
ASCII protocol on the master end, exactly as a CANable-style USB adapter does
on /dev/ttyACM0. A host on `slcan://PATH` then sees an ordinary adapter, so
host and robots run as separate processes without vcan.

Adapter side of the protocol (each command ends in CR):
    O / L / C        open / open listen-only / close the channel      -> CR
    Sn / sXXYY       bit rate (index 0..8) / BTR registers            -> CR
    V / v / N / F    hardware+firmware version / serial / status      -> Vhhff / NXXXX / Fxx
    tIIIL<data>      send a standard frame                            -> z CR
    TIIIIIIIIL<data> send an extended frame                           -> Z CR
    riiiL / Riii..L  remote frames                                    -> z / Z CR
    anything else                                                     -> BEL
Frames from the bus go to the host as tIIIL<data> CR (only while open).
When the host does not read, output queues up to MAX_PENDING bytes and then
whole frames are dropped (counted), never cut in half.
"""

from __future__ import annotations

import errno
import fcntl
import logging
import os
import select
import time
import tty
from collections import deque
from pathlib import Path
from typing import Any

import can

from bridge.links.errors import LinkError

log = logging.getLogger(__name__)

MAX_PENDING = 64 * 1024
BITRATES = {0: 10_000, 1: 20_000, 2: 50_000, 3: 100_000, 4: 125_000, 5: 250_000,
            6: 500_000, 7: 800_000, 8: 1_000_000}


class SlcanPtyBus(can.BusABC):
    def __init__(self, channel: str, bitrate: int | None = None, **kwargs: Any) -> None:
        self.link_path = Path(channel)
        self.master, self.slave = os.openpty()
        tty.setraw(self.slave)
        fl = fcntl.fcntl(self.master, fcntl.F_GETFL)
        fcntl.fcntl(self.master, fcntl.F_SETFL, fl | os.O_NONBLOCK)
        self.slave_name = os.ttyname(self.slave)
        try:
            if self.link_path.is_symlink() or self.link_path.exists():
                self.link_path.unlink()
            self.link_path.symlink_to(self.slave_name)
        except OSError as err:
            os.close(self.master)
            os.close(self.slave)
            raise LinkError(f"slcan-pty://{channel}: cannot link the pty there: {err}") from err
        self.is_open = False
        self.bitrate = bitrate
        self.inbuf = bytearray()
        self.pending = bytearray()
        self.frames: deque[can.Message] = deque()
        self.dropped = 0
        self.commands = 0
        self._shut = False
        self.channel_info = f"SLCAN face on {self.slave_name} ({channel})"
        super().__init__(channel=channel, **kwargs)

    # -- master side I/O ---------------------------------------------------------

    def _flush_out(self) -> None:
        while self.pending:
            try:
                n = os.write(self.master, self.pending)
            except BlockingIOError:
                return
            except OSError as err:
                if err.errno in (errno.EIO, errno.EAGAIN):
                    return
                raise can.CanOperationError(f"pty write: {err}") from err
            del self.pending[:n]

    def _reply(self, text: bytes) -> None:
        self.pending += text
        self._flush_out()

    def _read_master(self, timeout: float | None) -> None:
        self._flush_out()
        r, _, _ = select.select([self.master], [], [], timeout)
        if not r:
            return
        try:
            data = os.read(self.master, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError as err:
            if err.errno == errno.EIO:     # no host on the slave end
                return
            raise can.CanOperationError(f"pty read: {err}") from err
        self.inbuf += data
        while True:
            i = self.inbuf.find(b"\r")
            if i < 0:
                if len(self.inbuf) > 1024:
                    self.inbuf.clear()
                return
            line = bytes(self.inbuf[:i]).lstrip(b"\n")
            del self.inbuf[:i + 1]
            self._command(line)

    def _command(self, line: bytes) -> None:
        self.commands += 1
        if not line:
            self._reply(b"\r")
            return
        c = line[:1]
        try:
            if c in (b"O", b"L"):
                self.is_open = True
                self._reply(b"\r")
            elif c == b"C":
                self.is_open = False
                self._reply(b"\r")
            elif c == b"S" and int(line[1:2]) in BITRATES:
                self.bitrate = BITRATES[int(line[1:2])]
                self._reply(b"\r")
            elif c in (b"s", b"Z", b"M", b"m", b"X", b"W", b"Y", b"Q"):
                self._reply(b"\r")
            elif c == b"V":
                self._reply(b"V1013\r")
            elif c == b"v":
                self._reply(b"v1013\r")
            elif c == b"N":
                self._reply(b"NTS01\r")
            elif c == b"F":
                self._reply(b"F00\r")
            elif c in (b"t", b"r", b"T", b"R"):
                ext = c in (b"T", b"R")
                n = 8 if ext else 3
                ident = int(line[1:1 + n], 16)
                dlc = int(line[1 + n:2 + n])
                remote = c in (b"r", b"R")
                data = b"" if remote else bytes.fromhex(line[2 + n:2 + n + 2 * dlc].decode())
                if dlc > 8 or (not remote and len(data) != dlc):
                    raise ValueError("bad length")
                if self.is_open:
                    self.frames.append(can.Message(
                        arbitration_id=ident, is_extended_id=ext, is_remote_frame=remote,
                        dlc=dlc, data=data, timestamp=time.time(), channel=self.channel_info))
                self._reply(b"Z\r" if ext else b"z\r")
            else:
                self._reply(b"\a")
        except (ValueError, UnicodeDecodeError):
            self._reply(b"\a")

    # -- python-can bus ------------------------------------------------------------

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message | None, bool]:
        if self.frames:
            return self.frames.popleft(), False
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            self._read_master(left)
            if self.frames:
                return self.frames.popleft(), False
            if deadline is not None and time.monotonic() >= deadline:
                return None, False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        self._read_master(0.0)
        if not self.is_open:
            self.dropped += 1
            return
        if msg.is_extended_id:
            line = "T%08X%d" % (msg.arbitration_id, msg.dlc)
        else:
            line = "t%03X%d" % (msg.arbitration_id, msg.dlc)
        line += bytes(msg.data).hex().upper() + "\r"
        if len(self.pending) > MAX_PENDING:
            self.dropped += 1
            return
        self.pending += line.encode()
        self._flush_out()

    def shutdown(self) -> None:
        if self._shut:
            return
        self._shut = True
        super().shutdown()
        for fd in (self.master, self.slave):
            try:
                os.close(fd)
            except OSError:
                pass
        try:
            if self.link_path.is_symlink():
                self.link_path.unlink()
        except OSError:
            pass


def open_pty_bus(channel: str, bitrate: int | None = None) -> SlcanPtyBus:
    return SlcanPtyBus(channel, bitrate=bitrate)
