"""The HAL contract (tests/test_hal_contract.py) against the MicroPython
tether body: `TetherHal` (firmware_logic/board.py) run by CPython, framing
every call over an in-memory serial line to the host side it tethers to,
`TetherTransport` (sim_backend/emulators/tether.py) serving the sim world.
The clauses are CPython test code calling the body, so they run the body
under CPython; the same module under the real MicroPython interpreter, over
a pty, runs whole missions in hil_tests/test_micropython_robot.py.

No thread and no clock: the line is two byte queues, and a board read that
finds nothing waiting lets the host side serve first, so an answer is in
the queue as soon as the host gives it. A read that still finds nothing is
the board's timeout (the host had nothing more to say): TetherHal asks
again, as over a real line.
"""

from __future__ import annotations

from collections import deque

from bridge.transport import Message
from firmware_logic import framing
from firmware_logic import messages as msg
from firmware_logic.board import TetherHal
from firmware_logic.hal import WALL
from sim_backend.emulators.tether import TetherTransport
from sim_backend.engine import Engine
from sim_backend.scenario import validate
from tests.test_hal_contract import SCENARIO, HalContract, placed

NODE = 1


class HostEnd:
    """The host's end of the line (sim_backend/link.py HostEnd): decoding
    what the board wrote and queueing what the host sends for the board to read."""

    def __init__(self, to_host: deque, to_board: deque) -> None:
        self.to_host = to_host
        self.to_board = to_board
        self.dec = framing.Decoder()
        self.enc = framing.Encoder()

    def poll(self, timeout: float) -> list[Message]:
        # everything the board wrote is already here: nothing to wait for
        out: list[Message] = []
        d = self.dec
        while self.to_host:
            if d.feed(self.to_host.popleft()):
                out.append((d.node, d.kind, tuple(d.fields[:d.nfields])))
        return out

    def send(self, node: int, kind: int, fields: tuple) -> None:
        args = list(fields) + [0] * (6 - len(fields))
        n = self.enc.frame(kind, node, *args)
        self.to_board.extend(self.enc.out[:n])

    def bad_frames(self) -> dict[str, int]:
        return self.dec.error_counts()

    def close(self) -> None:
        pass


class BoardEnd:
    """The board's port as board.py wants it: read(timeout_ms) -> a byte or
    -1, write(buf, n), ms(). `serve()` runs the host side when the board would
    otherwise wait. The clock is simulated: a read that times out has waited
    its whole timeout, a byte takes `byte_ms`."""

    def __init__(self, to_host: deque, to_board: deque) -> None:
        self.to_host = to_host
        self.to_board = to_board
        self.serve = lambda: None
        self.now = 0
        self.byte_ms = 0

    def ms(self) -> int:
        return self.now & 0x3FFFFFFF

    def read(self, timeout_ms: int) -> int:
        if not self.to_board:
            self.serve()
        if self.to_board:
            self.now += self.byte_ms
            return self.to_board.popleft()
        self.now += timeout_ms
        return -1

    def write(self, buf: bytearray, n: int) -> None:
        self.to_host.extend(buf[:n])


class TestTetherHal(HalContract):
    def make(self):
        e = Engine(validate(SCENARIO), 1)
        placed(e.world)
        for b in e.bodies:
            b.reset_intents()
        to_host: deque = deque()
        to_board: deque = deque()
        tether = TetherTransport(HostEnd(to_host, to_board), e, [NODE])
        self.up: list[Message] = []      # what the tether passed on to the host

        def serve() -> None:
            self.up += tether.poll(0.0)

        port = BoardEnd(to_host, to_board)
        port.serve = serve
        hal = TetherHal(port, NODE)

        def tick():
            # end_tick returns 0 when the host never applied the tick: that
            # would make every clause after a tick pass or fail by accident
            assert hal.end_tick() == 1, "the host did not apply the tick"
            serve()
            assert hal.lost == 0 and tether.bad_frames() == {}
        return hal, tick

    def test_reports_reach_the_host_unchanged(self) -> None:
        """The tether passes the robot's own messages through (what the
        contract's "every report kind can be sent" cannot see from the body)."""
        from tests.test_hal_contract import UP_KINDS
        hal, tick = self.make()
        for j, kind in enumerate(UP_KINDS):
            hal.send(kind, j + 1, 1, 1, 1, 1, 1)
        tick()
        assert [(n, k) for n, k, _ in self.up] == [(NODE, k) for k in UP_KINDS]
        assert [f[0] for _, _, f in self.up] == list(range(1, len(UP_KINDS) + 1))


class TestTetherDeadline:
    """A request's answer has a deadline on the port's clock, not a silence:
    traffic that is not the answer (a host repeating HALT, ACKs, line noise)
    never holds a request back from its resend. Before, TetherHal waited for
    200 ms without a byte, so a host sending HALT every 100 ms while the
    request had been lost (the port vanished) stalled the board for good."""

    def flooded(self, noise: bytes) -> tuple[TetherHal, BoardEnd, list[bytes]]:
        to_host: deque = deque()
        to_board: deque = deque()
        host = HostEnd(to_host, to_board)
        port = BoardEnd(to_host, to_board)
        port.byte_ms = 10            # 16 bytes of HALT: 160 ms, never 200 ms of silence
        requests: list[bytes] = []
        fed = [0]

        def serve() -> None:
            # the host never answers (the request was lost) but keeps talking
            fed[0] += 1
            assert fed[0] < 10_000, "the board never gave up waiting (hang guard)"
            for _, kind, _f in host.poll(0.0):
                requests.append(bytes([kind]))
            if noise:
                to_board.extend(noise)
            else:
                host.send(0, msg.HALT, (0,))

        port.serve = serve
        return TetherHal(port, NODE), port, requests

    def test_a_request_is_resent_every_reply_ms_while_other_frames_arrive(self) -> None:
        hal, port, requests = self.flooded(b"")
        hal.retries = 4
        assert hal.probe(0) == WALL                # never answered: the safe default
        assert hal.lost == 1 and hal.resent == 3
        assert requests == [bytes([msg.SENSOR])] * 4
        # each wait ended at its deadline (200 ms), not after silence
        assert port.now == 4 * hal.reply_ms
        assert hal.halted == 1                     # the HALTs were kept for the FSM

    def test_line_noise_never_holds_a_request_back(self) -> None:
        hal, port, requests = self.flooded(b"\x13\x37garbage\xff\x05\x01")
        hal.retries = 3
        assert hal.end_tick() == 0                 # END never answered
        assert hal.lost == 1 and hal.resent == 2 and len(requests) == 3
        assert port.now <= 3 * (hal.reply_ms + port.byte_ms)


def test_the_board_ends_a_run_with_stop_and_the_tether_records_it() -> None:
    """board.run's last frame is ACTION STOP (the loop has ended): what a host
    waits for before it takes the port back (the REPL), instead of silence."""
    from firmware_logic import board
    e = Engine(validate(SCENARIO), 1)
    placed(e.world)
    to_host: deque = deque()
    to_board: deque = deque()
    tether = TetherTransport(HostEnd(to_host, to_board), e, [NODE])
    port = BoardEnd(to_host, to_board)
    served: list[int] = []

    def serve() -> None:
        assert NODE not in tether.stopped, "the board went on after STOP"
        tether.poll(0.0)
        served.append(tether.applied_ticks)

    port.serve = serve
    from sim_backend import registry
    thesis = registry.load("thesis")
    robot = thesis.make_robot(NODE, 1, validate({"behaviour": "thesis"}))
    hal = board.run(port, NODE, robot, thesis.spec, 5, 2)
    assert NODE not in tether.stopped             # written, not yet read by the host
    tether.poll(0.0)
    assert tether.stopped == {NODE: 5} and hal.tick == 5
    assert tether.applied_ticks == 5 and hal.lost == 0
