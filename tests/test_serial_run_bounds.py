"""The bytes around a board's run on its serial line, fed through a pty to
SerialTransport as the host reads them (bridge/serial/transport.py,
firmware_logic/framing.py Decoder.hunt).

The REPL text below was captured on MicroPython's unix port behind a pty
(hil_tests/test_mission_start.py's set-up): a mission that outlived the
board's run read the raw REPL's end of output and its answers to the host's
next frames right after the board's STOP frame, and logged "bad frame
(overflow)" (the run dabb985 dropped its test for). Each test waits on the
frame after the REPL's bytes, never on time."""

from __future__ import annotations

import logging
import select
import time

import pytest

from bridge.serial.pty import VirtualPort
from bridge.serial.transport import SerialTransport
from firmware_logic import board
from firmware_logic import messages as msg

# mpremote exec --no-follow (deploy --start): the raw REPL's prompt, the
# raw-paste header (its window size, 128, is little endian: a 0x00), its
# flow-control byte and the ack of the code; the program starts right after
RAW_PASTE_START = b"raw REPL; CTRL-B to exit\r\n>R\x01\x80\x00\x01\x04"
# after the board's last frame: the raw REPL's end of output (no error), then
# its answers to the host's next frames (a 0x01 in one: Ctrl-A, a 0x02: Ctrl-B)
AFTER_RUN = (b"\x04\x04>raw REPL; CTRL-B to exit\r\n>raw REPL; CTRL-B to exit\r\n>\r\n"
             b"MicroPython 9458e3a23f on 2026-07-05; linux [GCC 14.2.1] version\r\n"
             b"Type \"help()\" for more information.\r\n>>> ")
HANG_GUARD_S = 30.0


def run_frames(t: SerialTransport, node: int, ticks: int) -> list[tuple]:
    """A board's run as messages: a SENSOR query and an END per tick, then STOP."""
    out: list[tuple] = []
    for tick in range(ticks):
        out.append((node, msg.SENSOR, (tick, 2 * tick % 256, 1, 0, 0)))
        out.append((node, msg.ACTION, (tick, (2 * tick + 1) % 256, board.A_END, 0, 0)))
    out.append((node, msg.ACTION, (ticks, (2 * ticks) % 256, board.A_STOP, 0, 0)))
    return out


def wire(t: SerialTransport, messages: list[tuple]) -> bytes:
    return b"".join(t.encode(n, k, f) for n, k, f in messages)


def receive(t: SerialTransport, count: int) -> list[tuple]:
    got: list[tuple] = []
    end = time.monotonic() + HANG_GUARD_S          # hang guard: waits on the frames
    while len(got) < count:
        assert time.monotonic() < end, (got, t.bad_frames())
        got += t.poll(0.05)
    return got


def outside(*junk: bytes) -> int:
    """What the decoder passes over: every byte of the junk but its delimiters."""
    return sum(len(j) - j.count(0) for j in junk)


def test_the_repl_after_a_run_is_no_bad_frame(caplog: pytest.LogCaptureFixture) -> None:
    """Every frame of the run arrives, the REPL's bytes after STOP are
    skipped, and the board's next run is heard."""
    with VirtualPort() as vp, SerialTransport(vp.path, timeout=0.02) as t:
        first, second = run_frames(t, 1, 5), run_frames(t, 1, 1)[:1]
        vp.write(wire(t, first) + AFTER_RUN + wire(t, second))
        assert receive(t, len(first) + 1) == first + second
        assert t.bad_frames() == {}
        assert not [r for r in caplog.records if r.levelno >= logging.WARNING]
        assert t.skipped == outside(AFTER_RUN)


def test_a_deploy_start_while_the_host_holds_the_port_is_no_bad_frame() -> None:
    """The raw-paste header's 0x00 is not the start of framing: the bytes
    after it up to the program's first frame are skipped too."""
    with VirtualPort() as vp, SerialTransport(vp.path, timeout=0.02) as t:
        first, second = run_frames(t, 1, 2), run_frames(t, 1, 2)
        vp.write(RAW_PASTE_START + wire(t, first) + AFTER_RUN + RAW_PASTE_START + wire(t, second))
        assert receive(t, len(first) + len(second)) == first + second
        assert t.bad_frames() == {}
        assert t.skipped == outside(RAW_PASTE_START, AFTER_RUN, RAW_PASTE_START)


def test_garbage_inside_a_run_is_still_a_bad_frame() -> None:
    with VirtualPort() as vp, SerialTransport(vp.path, timeout=0.02) as t:
        run = run_frames(t, 1, 2)
        vp.write(wire(t, run[:2]) + b"\x00" + b"x" * 40 + wire(t, run[2:]))
        assert receive(t, len(run)) == run
        assert t.bad_frames() == {"overflow": 1}
        assert t.skipped == 0


def test_nothing_is_sent_to_a_board_whose_run_has_ended() -> None:
    """Its REPL would read a frame as keystrokes (0x01 Ctrl-A, 0x04 Ctrl-D
    runs what it holds); once the board is heard again, sends go on."""
    with VirtualPort() as vp, SerialTransport(vp.path, timeout=0.02) as t:
        run = run_frames(t, 1, 1)
        vp.write(wire(t, run))
        receive(t, len(run))
        t.send(1, msg.HALT, (0,))
        t.send(msg.HOST, msg.HALT, (0,))
        assert t.sends_after_stop == 2 and t.frames_out == 0
        again = run_frames(t, 1, 1)[:1]
        vp.write(wire(t, again))
        assert receive(t, 1) == again
        t.send(1, msg.ACK, (7,))
        want = t.encode(1, msg.ACK, (7,))
        seen = b""
        end = time.monotonic() + HANG_GUARD_S       # hang guard; waits on the bytes
        while len(seen) < len(want):
            assert time.monotonic() < end, seen
            r, _, _ = select.select([vp.master], [], [], 0.1)
            if r:
                seen += vp.read()
        assert seen == want            # the two HALTs never reached the line
