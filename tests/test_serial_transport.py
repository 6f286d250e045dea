"""SerialTransport on pyserial's loop:// and on a pty (bridge/serial/transport.py)."""

from __future__ import annotations

import select
import time
from types import SimpleNamespace

import pytest

from bridge.serial.errors import SerialOpenError
from bridge.serial.pty import VirtualPort
from bridge.serial.transport import SerialTransport, resolve_url
from firmware_logic import messages as msg


def test_url_forms() -> None:
    assert resolve_url("/dev/ttyUSB0") == ("/dev/ttyUSB0", {})
    assert resolve_url("loop://") == ("loop://", {})
    assert resolve_url("serial:///dev/ttyUSB0?baud=57600") == ("/dev/ttyUSB0", {"baud": "57600"})
    with pytest.raises(SerialOpenError, match=r"unknown option 'parity'.*serial:///dev/ttyUSB0\?baud="):
        resolve_url("serial:///dev/ttyUSB0?parity=E")
    with pytest.raises(SerialOpenError, match="not a number"):
        resolve_url("serial:///dev/ttyUSB0?baud=fast")


def test_missing_device_is_a_clear_error() -> None:
    with pytest.raises(SerialOpenError, match=r"cannot open serial port '/nonexistent/tty'"):
        SerialTransport("/nonexistent/tty")


def test_loopback_roundtrip_and_garbage() -> None:
    with SerialTransport("loop://", 115200, timeout=0.01) as t:
        t.send(5, msg.TOUCH, (1, 2, 3, 4, 5, 100))
        t._ser.write(b"\x01\x02garbage")          # type: ignore[union-attr]
        t.send(5, msg.HELLO, (1, 100, 1))
        got = t.poll(0.2)
        assert got == [(5, msg.TOUCH, (1, 2, 3, 4, 5, 100)), (5, msg.HELLO, (1, 100, 1))]
        assert t.nodes == {5}
        t._ser.write(b"\x00\x05\x01\x02\x00")     # type: ignore[union-attr]
        assert t.poll(0.05) == []
        assert t.bad_frames() == {"cobs": 2}   # the garbage earlier, and this frame
    t.close()   # idempotent


def test_poll_returns_at_its_deadline_on_a_silent_port(monkeypatch: pytest.MonkeyPatch) -> None:
    """On a simulated clock (each read of the silent port takes the port's
    timeout): poll(0.125) reads 4 times and returns, whatever the machine's
    load. No wall-clock figure: speed is measured in bench/."""
    import bridge.serial.transport as transport
    with SerialTransport("loop://", timeout=0.03125) as t:
        now = [0.0]
        monkeypatch.setattr(transport, "time",
                            SimpleNamespace(monotonic=lambda: now[0], sleep=time.sleep))
        ser = t._ser
        assert ser is not None
        real_read = ser.read
        reads = [0]

        def read(n: int) -> bytes:
            reads[0] += 1
            assert reads[0] < 1000, "poll never returned (hang guard)"
            now[0] += 0.03125
            return real_read(n)

        monkeypatch.setattr(ser, "read", read)
        assert t.poll(0.125) == []
        assert reads[0] == 4 and now[0] == 0.125


def test_port_that_disappears_and_comes_back() -> None:
    with VirtualPort() as vp, SerialTransport(vp.path, timeout=0.02, reopen_every=0.02) as t:
        enc = t.encode(3, msg.ACK, (7,))
        vp.write(enc)
        assert t.poll(0.5) == [(3, msg.ACK, (7,))]
        vp.vanish()
        assert t.poll(0.1) == []                  # no hang, no exception
        t.send(3, msg.ACK, (1,))                  # dropped and counted
        assert t.bad_frames()["disconnect"] == 1
        vp.come_back()
        deadline = time.monotonic() + 30       # hang guard: waits for the reopen
        got: list = []
        while not got and time.monotonic() < deadline:
            vp.write(enc)
            got = t.poll(0.05)
        assert got and got[0] == (3, msg.ACK, (7,))
        assert t.connected
        t.send(3, msg.HALT, (0,))
        want = t.encode(3, msg.HALT, (0,))
        seen = b""
        deadline = time.monotonic() + 10          # hang guard; waits on the bytes
        while len(seen) < len(want):
            assert time.monotonic() < deadline, seen
            r, _, _ = select.select([vp.master], [], [], 0.1)
            if r:
                seen += vp.read()
        assert seen == want


# what `deploy --start` leaves on the line: the REPL's banner and prompts, no 0x00
REPL_LEFTOVER = (b"MicroPython v1.22.2 on 2024-02-22; linux [GCC 12.2.0] version\r\n"
                 b"Use Ctrl-D to exit, Ctrl-E for paste mode\r\n>>> import main\r\n")


def test_output_before_the_first_frame_is_skipped_but_later_garbage_counted(
        caplog: pytest.LogCaptureFixture) -> None:
    """A mission joining a board's line after deploy --start: the REPL's
    leftover output is no bad frame (nor a warning); garbage after framing
    started still is."""
    with VirtualPort() as vp, SerialTransport(vp.path, timeout=0.02) as t:
        hello, ack = t.encode(1, msg.HELLO, (1, 100, 1)), t.encode(1, msg.ACK, (7,))
        vp.write(REPL_LEFTOVER + hello)
        got: list = []
        deadline = time.monotonic() + 30          # hang guard: waits on the bytes
        while not got:
            assert time.monotonic() < deadline
            got += t.poll(0.05)
        assert got == [(1, msg.HELLO, (1, 100, 1))]
        assert t.bad_frames() == {} and t.skipped == len(REPL_LEFTOVER)
        assert not [r for r in caplog.records if r.levelname == "WARNING"]
        vp.write(b"\x00" + b"x" * 40 + b"\x00" + ack)   # a frame too long, then a good one
        while len(got) < 2:
            assert time.monotonic() < deadline
            got += t.poll(0.05)
        assert got[1] == (1, msg.ACK, (7,))
        assert t.bad_frames() == {"overflow": 1}
        assert t.skipped == len(REPL_LEFTOVER)
