"""The Khepera II driver against the emulator, and the emulator on its own."""

from __future__ import annotations

import time

import pytest
import serial

from bridge.serial.errors import ProtocolError, SerialTimeout
from bridge.serial.khepera import KheperaII
from sim_backend.emulators.khepera import KheperaEmulator


def test_emulator_answers_the_protocol_by_hand() -> None:
    # raw bytes, no driver: the emulator follows the documented protocol
    with KheperaEmulator(baud=115200) as emu:
        with serial.Serial(emu.path, 115200, timeout=0.5) as s:
            for req, want in ((b"B\r", b"b,5.01,5.00\r\n"), (b"D,5,-5\r", b"d\r\n"),
                              (b"E\n", b"e,5,-5\r\n"), (b"X\r", b"Command not found\r\n"),
                              (b"D,1\r", b"z,Protocol error\r\n"), (b"G,0,0\r", b"g\r\n")):
                s.reset_input_buffer()
                s.write(req)
                assert s.read_until(b"\n") == want, req


def test_line_time_follows_the_baud_rate() -> None:
    with KheperaEmulator(baud=9600) as emu, KheperaII(emu.path, 9600) as k:
        start = time.monotonic()
        for _ in range(5):
            k.proximity()
        took = time.monotonic() - start
    # "N\r" + "n,v0..v7\r\n" (>= 20 bytes) x 11 bits at 9600 baud >= 23 ms each
    assert took >= 5 * 22 * 11 / 9600


def test_wrong_baud_is_a_clear_error() -> None:
    with KheperaEmulator(baud=38400) as emu, KheperaII(emu.path, 9600, timeout=0.2) as k:
        with pytest.raises((ProtocolError, SerialTimeout), match="baud"):
            k.version()


def test_garbage_and_truncated_replies_are_retried() -> None:
    with KheperaEmulator(baud=115200) as emu, KheperaII(emu.path, 115200, timeout=0.2) as k:
        emu.garbage_next = b"\x00\xffnoise\r\n"
        assert len(k.proximity()) == 8
        emu.truncate_next = 3
        assert len(k.ambient()) == 8
        emu.mute_next = 1
        assert k.counters() == k.counters()
        assert k.retried >= 2
        emu.mute_next = 10
        with pytest.raises(SerialTimeout, match="did not answer"):
            k.counters()


def test_port_that_disappears_raises_instead_of_hanging() -> None:
    with KheperaEmulator(baud=115200) as emu, KheperaII(emu.path, 115200, timeout=0.2) as k:
        k.version()
        emu.vanish()
        with pytest.raises((SerialTimeout, ProtocolError)):
            k.counters()
        emu.come_back()
    with KheperaEmulator(baud=115200) as emu2:
        with KheperaII(emu2.path, 115200) as k2:     # reopened: works again
            assert k2.version() == ("5.01", "5.00")
