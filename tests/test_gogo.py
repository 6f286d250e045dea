"""The GoGo Board driver (bridge/serial/gogo.py) against the emulator on a pty,
and the emulator on its own: raw protocol bytes, line time, and every fault
of a serial line (garbage, truncated replies, bad echo, silence, wrong baud,
a port that disappears and comes back): a clear error or a resync, never a hang.

No assertion here depends on how fast the machine is: waits are on
conditions (bytes in the port), and "never a hang" is the number of tries
the error reports, each bounded by the port's timeout."""

from __future__ import annotations

import time

import pytest
import serial

from bridge.errors import BridgeError, UsageError
from bridge.serial.errors import (PortClosedError, ProtocolError, SerialLinkError,
                                  SerialOpenError, SerialPortLost, SerialTimeout)
from bridge.serial.gogo import GoGoBoard
from sim_backend.emulators.gogo import GoGoEmulator

BAUD = 9600


def exchange(s: serial.Serial, req: bytes, reply_len: int) -> bytes:
    s.reset_input_buffer()
    s.write(req)
    return s.read(len(req) + reply_len)


def test_emulator_answers_the_protocol_by_hand() -> None:
    # raw bytes, no driver: the emulator follows the documented protocol
    with GoGoEmulator(baud=BAUD) as emu, serial.Serial(emu.path, BAUD, timeout=0.3) as s:
        assert exchange(s, b"\x54\xfe\x00", 3) == b"\x54\xfe\x00\x55\xff\xaa"       # ping
        # sensor 1, normal: closed/open switch levels, high byte masked to 2 bits
        got = exchange(s, b"\x54\xfe\x20", 4)
        assert got[:5] == b"\x54\xfe\x20\x55\xff" and got[5] <= 3
        assert got[5] << 8 | got[6] == emu.reading(1) > 1000      # nothing touching
        got = exchange(s, b"\x54\xfe\x3e", 4)                     # sensor 8, min mode
        assert got == b"\x54\xfe\x3e\x55\xff\x03\xff"             # unwired: floats high
        assert exchange(s, b"\x54\xfe\x80\x03", 3) == b"\x54\xfe\x80\x03\x55\xff\xaa"
        assert emu.selected == 3
        assert exchange(s, b"\x54\xfe\x6c", 3)[-1] == 0xAA        # power 3
        assert emu.motor_power[1] == emu.motor_power[2] == 3 and emu.motor_power[4] == 7
        assert exchange(s, b"\x54\xfe\x50", 3)[-1] == 0xAA        # that way
        assert exchange(s, b"\x54\xfe\x48", 3)[-1] == 0xAA        # reverse: this way
        assert emu.motor_dir[1] == 1
        assert exchange(s, b"\x54\xfe\x40", 3)[-1] == 0xAA        # on
        assert emu.motor_on[1] and emu.motor_on[2] and not emu.motor_on[4]
        assert exchange(s, b"\x54\xfe\x54", 3)[-1] == 0xAA        # coast
        assert not emu.motor_on[1]
        assert exchange(s, b"\x54\xfe\xc0", 3)[-1] == 0xAA and emu.led == 1
        assert exchange(s, b"\x54\xfe\xc1", 3)[-1] == 0xAA and emu.led == 0
        assert exchange(s, b"\x54\xfe\xc4", 3)[-1] == 0xAA and emu.beeps == 1
        # junk before the header is echoed and ignored; an unknown command is
        # echoed and not answered
        assert exchange(s, b"\x12\x54\xfe\x00", 3) == b"\x12\x54\xfe\x00\x55\xff\xaa"
        assert exchange(s, b"\x54\xfe\xe0", 3) == b"\x54\xfe\xe0"
        assert emu.unknown == 1


def test_line_time_follows_the_baud_rate() -> None:
    with GoGoEmulator(baud=BAUD) as emu, GoGoBoard(emu.path, BAUD) as b:
        for n in range(1, 9):
            assert 0 <= b.sensor(n) <= 1023
    # each read: 3 request bytes echoed + 4 reply bytes, 10 bits each at 9600 baud
    assert emu.line_time == pytest.approx(8 * 7 * 10 / 9600)


def test_emulator_refuses_what_the_protocol_does_not_define() -> None:
    # strict on purpose: no reply to a command outside the table, nothing done
    with GoGoEmulator(baud=BAUD) as emu, serial.Serial(emu.path, BAUD, timeout=0.3) as s:
        assert exchange(s, b"\x54\xfe\x80\x03", 3)[-1] == 0xAA
        for req in (b"\x54\xfe\x23",          # sensor 1, mode 3: no such mode
                    b"\x54\xfe\x80\x13",      # select with a bit above D
                    b"\x54\xfe\x41",          # motor on with its low bits set
                    b"\x54\xfe\x62"):         # power with its low bits set
            assert exchange(s, req, 3) == req, req.hex()      # echoed only
        assert emu.unknown == 4 and emu.selected == 3
        assert not emu.motor_on[1] and emu.motor_power[1] == 7
        assert exchange(s, b"\x54\xfe\x00", 3) == b"\x54\xfe\x00\x55\xff\xaa"


def test_garbage_is_skipped_and_bad_replies_are_retried() -> None:
    with GoGoEmulator(baud=BAUD) as emu, GoGoBoard(emu.path, BAUD, timeout=0.2,
                                                    quiet=0.05) as b:
        want = emu.reading(5)
        emu.noise_next = b"\x00\xff\x55\x13"            # before the echo
        assert b.sensor(5) == want and b.retried == 0
        emu.garbage_next = b"\xaa\x07\x55"              # between the echo and 55 ff
        assert b.sensor(5) == want and b.retried == 0
        assert b.junk == 7
        emu.pty.write(b"\x55\xff\xaa\x99")              # stale junk: flushed
        deadline = time.monotonic() + 5
        while b.ser.in_waiting < 4:                     # wait until it is in the port
            assert time.monotonic() < deadline
            time.sleep(0.001)
        b.ping()
        emu.truncate_next = 3                           # 55 ff hi: low byte missing
        assert b.sensor(5) == want and b.retried == 1
        emu.corrupt_echo_next = 1                       # the board heard something else
        b.ping()
        assert b.retried == 2
        emu.mute_next = 1
        b.ping()
        assert b.retried == 3


def test_silent_board_is_a_timeout_not_a_hang() -> None:
    with GoGoEmulator(baud=BAUD) as emu, GoGoBoard(emu.path, BAUD, timeout=0.15) as b:
        emu.mute_next = 100
        # three tries, each ended by its 0.15 s deadline: bounded, not a hang
        with pytest.raises(SerialTimeout, match=r"did not answer ping \(54 fe 00\) within "
                                              r"0\.15 s \(3 tries\)"):
            b.ping()
        emu.mute_next = 0
        b.ping()                                        # and back in step


def test_a_reply_that_stays_bad_names_what_was_expected() -> None:
    with GoGoEmulator(baud=BAUD) as emu, GoGoBoard(emu.path, BAUD, timeout=0.2, retries=0,
                                                    quiet=0.05) as b:
        emu.truncate_next = 2
        with pytest.raises(ProtocolError, match="expected 55 ff then ACK aa, got 55 ff"):
            b.ping()
        emu.truncate_next = 3
        with pytest.raises(ProtocolError, match="two data bytes.*truncated"):
            b.sensor(2)
        b.ping()


def test_reverse_is_not_retried_once_the_board_heard_it() -> None:
    with GoGoEmulator(baud=BAUD) as emu, GoGoBoard(emu.path, BAUD, timeout=0.2,
                                                    quiet=0.05) as b:
        b.select("A")
        b.thisway()
        emu.truncate_next = 2
        with pytest.raises(ProtocolError, match="not idempotent"):
            b.reverse()
        assert emu.motor_dir[1] == -1                   # reversed exactly once
        emu.mute_next = 1                               # unheard: safe to retry
        b.reverse()
        assert emu.motor_dir[1] == 1 and b.retried == 1


def test_wrong_baud_is_a_clear_error() -> None:
    with GoGoEmulator(baud=BAUD) as emu:
        with GoGoBoard(emu.path, 19200, timeout=0.2, quiet=0.05) as b:
            with pytest.raises(ProtocolError, match="9600 baud.*19200 baud") as err:
                b.ping()
            assert isinstance(err.value, ProtocolError)
            assert emu.commands == 0                     # nothing garbled was obeyed
        with GoGoBoard(emu.path, BAUD) as b:             # right baud: fine at once
            b.ping()


def test_port_that_disappears_raises_and_reopens_when_it_comes_back() -> None:
    with GoGoEmulator(baud=BAUD) as emu, GoGoBoard(emu.path, BAUD, timeout=0.2) as b:
        b.ping()
        emu.vanish()
        with pytest.raises(SerialPortLost, match="port failed during"):
            b.sensor(1)
        calls = (b.ping, lambda: b.sensor(2), lambda: b.select("AB"), b.on, b.off,
                 lambda: b.power(3), lambda: b.led(True), b.beep)
        for call in calls:                      # every call while it is gone
            with pytest.raises(SerialPortLost, match="is gone") as err:
                call()
            # the serial package's promise: a SerialTimeout, one line, naming the port
            assert isinstance(err.value, SerialPortLost)
            assert isinstance(err.value, SerialTimeout)
            assert "\n" not in str(err.value) and b.port in str(err.value)
        emu.come_back()
        b.ping()
        assert b.reopened == 1 and b.sensor(8) == 1023


def test_close_is_idempotent_and_never_raises_even_on_a_dead_port() -> None:
    with GoGoEmulator(baud=BAUD) as emu:
        b = GoGoBoard(emu.path, BAUD, timeout=0.2)
        b.ping()
        emu.vanish()
        b.close()
        b.close()
        with pytest.raises(PortClosedError, match="closed") as err:
            b.ping()
        assert isinstance(err.value, PortClosedError)


def test_errors_share_one_root_and_bad_arguments_are_refused() -> None:
    """The board raises the serial package's errors, as the Khepera driver
    does (one tree, bridge/serial/errors.py); a bad argument is a UsageError."""
    for cls in (SerialTimeout, ProtocolError, SerialPortLost, SerialOpenError, PortClosedError):
        assert issubclass(cls, SerialLinkError) and issubclass(cls, BridgeError)
    assert issubclass(SerialPortLost, SerialTimeout)
    assert issubclass(UsageError, BridgeError) and issubclass(UsageError, ValueError)
    with pytest.raises(SerialOpenError, match="cannot open"):
        GoGoBoard("/nonexistent/ttyGOGO")
    with pytest.raises(SerialOpenError, match="unknown option"):
        GoGoBoard("gogo:///dev/ttyUSB0?speed=9600")
    with GoGoEmulator(baud=BAUD) as emu, GoGoBoard("gogo://%s?baud=9600" % emu.path) as b:
        b.ping()
        for bad in (lambda: b.sensor(0), lambda: b.sensor(9), lambda: b.sensor(1, 3),
                    lambda: b.power(8), lambda: b.select("E"), lambda: b.select(16)):
            with pytest.raises(UsageError):
                bad()
        assert emu.commands == 1
    with pytest.raises(PortClosedError, match="closed"):
        b.ping()
