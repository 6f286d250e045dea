"""Pseudo-terminals that look like USB serial ports, in pure Python (no socat).

- VirtualPort: one pty; the host opens `path` (a symlink to /dev/pts/N) as a
  serial port, we hold the master side. `vanish()` / `come_back()` model a
  USB adapter unplugged and plugged in again at the same path.
- PtyRelay: a program (e.g. `micropython`, the unix port) on its own raw pty,
  relayed to a VirtualPort, so `mpremote connect PATH` and SerialTransport
  talk to it as to a board. Faults for tests: inject bytes either way,
  filter (truncate, corrupt) what goes to the host, vanish and come back.

Both are context managers; close() is idempotent.
"""

from __future__ import annotations

import errno
import logging
import os
import select
import subprocess
import tempfile
import threading
import time
import tty
from types import TracebackType
from typing import Callable

log = logging.getLogger(__name__)


def _raw(fd: int) -> None:
    tty.setraw(fd)


class VirtualPort:
    """A pty reachable at `path`; `master` is our end (non-blocking)."""

    def __init__(self, path: str | None = None) -> None:
        self._tmpdir: str | None = None
        if path is None:
            self._tmpdir = tempfile.mkdtemp(prefix="touchswarm-pty-")
            path = os.path.join(self._tmpdir, "tty")
        self.path = path
        self.master = -1
        self._slave = -1
        self.generation = 0
        self._open()

    def _open(self) -> None:
        m, s = os.openpty()
        _raw(s)
        os.set_blocking(m, False)
        name = os.ttyname(s)
        # keep the slave open until a client has opened it; see settle()
        self.master, self._slave = m, s
        tmp = self.path + ".new"
        if os.path.lexists(tmp):
            os.unlink(tmp)
        os.symlink(name, tmp)
        os.replace(tmp, self.path)
        self.generation += 1

    @property
    def present(self) -> bool:
        return self.master >= 0

    def release_slave(self) -> None:
        """Close our own slave fd (after a client opened the port), so that the
        client closing the port is seen as EIO on the master."""
        if self._slave >= 0:
            os.close(self._slave)
            self._slave = -1

    def vanish(self) -> None:
        """The device disappears: the path goes, open clients get EIO."""
        self.release_slave()
        if self.master >= 0:
            os.close(self.master)
            self.master = -1
        if os.path.lexists(self.path):
            os.unlink(self.path)

    def come_back(self) -> None:
        """The device reappears at the same path (a new pty underneath)."""
        if self.master < 0:
            self._open()

    def write(self, data: bytes) -> int:
        """Write what fits; return the bytes written (0 when gone or full)."""
        if self.master < 0:
            return 0
        try:
            return os.write(self.master, data)
        except BlockingIOError:
            return 0
        except OSError as err:
            if err.errno == errno.EIO:
                return 0
            raise

    def read(self, n: int = 4096) -> bytes:
        if self.master < 0:
            return b""
        try:
            return os.read(self.master, n)
        except BlockingIOError:
            return b""
        except OSError as err:
            if err.errno == errno.EIO:     # no client has the port open
                return b""
            raise

    def close(self) -> None:
        self.vanish()
        if self._tmpdir is not None:
            try:
                os.rmdir(self._tmpdir)
            except OSError:
                pass
            self._tmpdir = None

    def __enter__(self) -> "VirtualPort":
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


class PtyRelay:
    """Run `argv` on a raw pty and relay it to a VirtualPort at `path`."""

    def __init__(self, argv: list[str], cwd: str | None = None, path: str | None = None,
                 env: dict[str, str] | None = None) -> None:
        self.port = VirtualPort(path)
        self.path = self.port.path
        m, s = os.openpty()
        _raw(s)
        os.set_blocking(m, False)
        self._child_master = m
        self.proc = subprocess.Popen(argv, stdin=s, stdout=s, stderr=s, cwd=cwd, env=env,
                                     close_fds=True, start_new_session=True)
        os.close(s)
        self.to_host_filter: Callable[[bytes], bytes] | None = None
        self.bytes_to_host = 0
        self.bytes_to_child = 0
        self.dropped_to_host = 0
        self._pending_to_child = b""
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="pty-relay", daemon=True)
        self._thread.start()

    # -- faults -------------------------------------------------------------------

    def inject_to_host(self, data: bytes) -> None:
        with self._lock:
            self.port.write(data)

    def inject_to_child(self, data: bytes) -> None:
        with self._lock:
            self._pending_to_child += data

    def vanish(self) -> None:
        with self._lock:
            self.port.vanish()

    def come_back(self) -> None:
        with self._lock:
            self.port.come_back()

    # -- relay ----------------------------------------------------------------------

    def _run(self) -> None:
        cm = self._child_master
        while not self._stop.is_set():
            with self._lock:
                hm = self.port.master
            fds = [cm] + ([hm] if hm >= 0 else [])
            try:
                r, _, _ = select.select(fds, [], [], 0.02)
            except (OSError, ValueError):
                time.sleep(0.01)
                continue
            if cm in r:
                try:
                    data = os.read(cm, 4096)
                except BlockingIOError:
                    data = b""
                except OSError:
                    return            # the child is gone
                if not data:
                    return
                with self._lock:
                    f = self.to_host_filter
                    if f is not None:
                        data = f(data)
                    sent = 0
                    deadline = time.monotonic() + 0.2
                    while sent < len(data) and self.port.present and time.monotonic() < deadline:
                        k = self.port.write(data[sent:])
                        if k == 0:
                            time.sleep(0.001)
                        sent += k
                    self.bytes_to_host += sent
                    self.dropped_to_host += len(data) - sent
            if hm >= 0 and hm in r:
                with self._lock:
                    data = self.port.read()
                if not data:
                    time.sleep(0.005)    # nobody has the port open (EIO): do not spin
                self._to_child(data)
            elif self._pending_to_child:
                self._to_child(b"")

    def _to_child(self, data: bytes) -> None:
        with self._lock:
            data = self._pending_to_child + data
            self._pending_to_child = b""
        while data:
            try:
                k = os.write(self._child_master, data)
            except BlockingIOError:
                time.sleep(0.001)
                continue
            except OSError:
                return
            self.bytes_to_child += k
            data = data[k:]

    def close(self) -> None:
        self._stop.set()
        if self.proc.poll() is None:
            self.proc.terminate()
            try:
                self.proc.wait(2)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(2)
        if self._thread.is_alive() and self._thread is not threading.current_thread():
            self._thread.join(2)
        if self._child_master >= 0:
            os.close(self._child_master)
            self._child_master = -1
        self.port.close()

    def __enter__(self) -> "PtyRelay":
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
