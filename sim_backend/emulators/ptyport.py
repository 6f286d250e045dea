"""The device end of a pseudo-terminal, for emulators.

`DevicePty` makes a pty whose slave is reachable at `path` (a symlink), and
reads the line speed the host set on it (on Linux the master sees the
slave's termios), so an emulator can model a wrong baud rate: a UART at the
wrong speed sees garbage. `Emulator` runs a device's byte handler in a
thread; subclasses implement `on_bytes(data)` and write replies with
`reply(data)`, which waits the modelled line time first.
"""

from __future__ import annotations

import errno
import os
import select
import tempfile
import termios
import threading
import time
import tty
from types import TracebackType

SPEEDS = {getattr(termios, "B%d" % b): b for b in
          (1200, 2400, 4800, 9600, 19200, 38400, 57600, 115200, 230400)}


class DevicePty:
    def __init__(self, path: str | None = None) -> None:
        self._tmpdir = None
        if path is None:
            self._tmpdir = tempfile.mkdtemp(prefix="touchswarm-emu-")
            path = os.path.join(self._tmpdir, "tty")
        self.path = path
        self.master = -1
        self._slave = -1
        self.open()

    def open(self) -> None:
        m, s = os.openpty()
        tty.setraw(s)
        os.set_blocking(m, False)
        self.master, self._slave = m, s     # our slave fd keeps the pty alive
        tmp = self.path + ".new"
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(os.ttyname(s), tmp)
        os.replace(tmp, self.path)

    def line_baud(self) -> int | None:
        """The baud rate the host set on its end (None when unknown)."""
        if self.master < 0:
            return None
        try:
            return SPEEDS.get(termios.tcgetattr(self.master)[4])
        except termios.error:
            return None

    def read(self) -> bytes:
        if self.master < 0:
            return b""
        try:
            return os.read(self.master, 4096)
        except BlockingIOError:
            return b""
        except OSError as err:
            if err.errno == errno.EIO:
                return b""
            raise

    def write(self, data: bytes) -> None:
        end = time.monotonic() + 0.5
        while data and self.master >= 0 and time.monotonic() < end:
            try:
                k = os.write(self.master, data)
            except BlockingIOError:
                time.sleep(0.001)
                continue
            except OSError:
                return
            data = data[k:]

    def vanish(self) -> None:
        for fd in (self._slave, self.master):
            if fd >= 0:
                os.close(fd)
        self.master = self._slave = -1
        if os.path.lexists(self.path):
            os.unlink(self.path)

    def come_back(self) -> None:
        if self.master < 0:
            self.open()

    def close(self) -> None:
        self.vanish()
        if self._tmpdir:
            try:
                os.rmdir(self._tmpdir)
            except OSError:
                pass
            self._tmpdir = None


class Emulator:
    """A device on a pty, answering in a thread. Context manager."""

    bits_per_byte = 10          # start + 8 data + stop (8N1)

    def __init__(self, baud: int, path: str | None = None) -> None:
        self.baud = baud
        self.pty = DevicePty(path)
        self.path = self.pty.path
        self._lock = threading.RLock()
        self._stop = threading.Event()
        self.line_time = 0.0           # seconds of modelled wire time so far
        self._thread = threading.Thread(target=self._run, name=type(self).__name__,
                                        daemon=True)

    def start(self) -> "Emulator":
        self._thread.start()
        return self

    def wire_seconds(self, nbytes: int) -> float:
        return nbytes * self.bits_per_byte / self.baud

    def baud_ok(self) -> bool:
        b = self.pty.line_baud()
        return b is None or b == self.baud

    @staticmethod
    def scramble(data: bytes) -> bytes:
        """What a UART at the wrong speed makes of bytes: other bytes."""
        return bytes(((b * 37) ^ 0xA5) & 0xFF for b in data)

    def reply(self, data: bytes, request_len: int = 0) -> None:
        """Send after the modelled line time of the request and the reply."""
        t = self.wire_seconds(request_len + len(data))
        self.line_time += t
        time.sleep(t)
        if not self.baud_ok():
            data = self.scramble(data)
        self.pty.write(data)

    def on_bytes(self, data: bytes) -> None:
        raise NotImplementedError

    def _run(self) -> None:
        while not self._stop.is_set():
            m = self.pty.master
            if m < 0:
                time.sleep(0.01)
                continue
            try:
                r, _, _ = select.select([m], [], [], 0.02)
            except (OSError, ValueError):
                time.sleep(0.01)
                continue
            if not r:
                continue
            data = self.pty.read()
            if not data:
                time.sleep(0.005)
                continue
            if not self.baud_ok():
                data = self.scramble(data)
            with self._lock:
                self.on_bytes(data)

    def vanish(self) -> None:
        with self._lock:
            self.pty.vanish()

    def come_back(self) -> None:
        with self._lock:
            self.pty.come_back()

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(2)
        self.pty.close()

    def __enter__(self) -> "Emulator":
        if not self._thread.is_alive():
            self.start()
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
