"""The Khepera II driver against the emulator, and the emulator on its own.

What survives what: an unplugged port is a typed error on every call and is
reopened when the robot is back; a single refused (garbled) request is line
noise and retried; the emulator refuses an overlong line as a whole."""

from __future__ import annotations

import pytest
import serial

from bridge.serial.errors import (PortClosedError, ProtocolError, SerialLinkError,
                                  SerialPortLost, SerialTimeout)
from bridge.serial.khepera import KheperaII
from sim_backend.emulators.khepera import BANNER, MAX_LINE, KheperaEmulator


def ask(s: serial.Serial, req: bytes) -> bytes:
    s.write(req)
    return s.read_until(b"\n")


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


def test_emulator_refuses_an_overlong_line_as_a_whole() -> None:
    with KheperaEmulator(baud=115200) as emu, \
            serial.Serial(emu.path, 115200, timeout=1.0) as s:
        s.reset_input_buffer()
        assert ask(s, b"D,1,1\r") == b"d\r\n"
        # the tail after byte 64 is a valid command: a lenient parser runs it
        assert ask(s, b"A" * (MAX_LINE + 1) + b"D,9,9\r") == b"z,Protocol error\r\n"
        # replies come in order: had the tail run, its `d` would come first
        assert ask(s, b"E\r") == b"e,1,1\r\n"
        assert emu.speed == [1, 1] and emu.refused == 1
        # exactly MAX_LINE bytes is still a line (padding a command with
        # zeros in its arguments keeps it valid)
        line = b"D,2," + b"0" * (MAX_LINE - 5) + b"2"
        assert len(line) == MAX_LINE and ask(s, line + b"\r") == b"d\r\n"
        assert emu.speed == [2, 2]


def test_emulator_is_strict_about_arguments() -> None:
    with KheperaEmulator(baud=115200) as emu, \
            serial.Serial(emu.path, 115200, timeout=1.0) as s:
        s.reset_input_buffer()
        for bad in (b"D, 5,5\r", b"D,+5,5\r", b"D,5_0,1\r", b"D,5,5,\r", b"D,0x5,1\r"):
            assert ask(s, bad) == b"z,Protocol error\r\n", bad
        for bad in (b" H\r", b"h\r", b"HH\r"):
            assert ask(s, bad) == b"Command not found\r\n", bad
        assert emu.speed == [0, 0] and emu.refused == 8


def test_line_time_follows_the_baud_rate() -> None:
    with KheperaEmulator(baud=9600) as emu, KheperaII(emu.path, 9600) as k:
        for _ in range(5):
            k.proximity()
        replies = b"".join(b"n," + b",".join(b"%d" % v for v in emu.proximity()) + b"\r\n"
                           for _ in range(5))
    # the modelled wire time: the power-up banner, then 5 x ("N\r" + the reply),
    # 11 bits a byte at 9600 baud
    assert emu.line_time == pytest.approx((len(BANNER) + 5 * 2 + len(replies)) * 11 / 9600)


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


def test_one_refused_request_is_line_noise_and_retried() -> None:
    with KheperaEmulator(baud=115200) as emu, KheperaII(emu.path, 115200, timeout=0.2) as k:
        emu.corrupt_request_next = 1          # the robot hears garbage: Command not found
        assert k.counters() == (0, 0)
        assert k.retried == 1 and emu.refused == 1
        emu.corrupt_request_next = 1
        bios, _ = k.version()
        assert bios == "5.01" and k.retried == 2
        emu.corrupt_request_next = 3          # refused every time: not noise any more
        with pytest.raises(ProtocolError, match=r"'Command not found' to 'H' on all 3 tries"):
            k.counters()
        assert emu.refused == 5


def test_unplug_is_a_typed_error_on_every_call_and_the_port_reopens() -> None:
    with KheperaEmulator(baud=115200) as emu, KheperaII(emu.path, 115200, timeout=0.2) as k:
        k.version()
        emu.vanish()
        calls = (k.counters, k.version, lambda: k.set_speed(1, 1), k.proximity,
                 k.ambient, lambda: k.led(0, 1), k.reset_counters, k.counters)
        for call in calls:
            with pytest.raises(SerialPortLost) as err:
                call()
            assert isinstance(err.value, SerialTimeout)      # what the docs promise
            assert "\n" not in str(err.value) and k.port in str(err.value)
        emu.come_back()
        assert k.version() == ("5.01", "5.00")              # the same object, reopened
        assert k.reopened == 1
        k.set_speed(3, 3)
        assert emu.speed == [3, 3]


def test_close_is_idempotent_never_raises_and_later_calls_say_closed() -> None:
    with KheperaEmulator(baud=115200) as emu:
        k = KheperaII(emu.path, 115200, timeout=0.2)
        k.version()
        emu.vanish()
        k.close()                             # on a dead port
        k.close()
        with pytest.raises(PortClosedError, match="closed") as err:
            k.counters()
        assert isinstance(err.value, SerialLinkError)
