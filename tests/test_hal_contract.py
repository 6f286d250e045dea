"""The HAL contract (firmware_logic/hal.py), written once and run against
bodies: every subclass below provides one body through `make()` and
inherits every clause. A body that cannot honour a clause names it in
`CANNOT`, with the reason; the clause then asserts that the reason is
given, never skips silently.

Bodies here: the simulated body (SimBody over a World), the batch engine's
body (BatchBody over flat arrays, here run by CPython: the batch engine
transforms and compiles this very class), the scripted body (the conformance fixture that
also runs on MicroPython). The serial bodies
(Khepera II, GoGo Board) on their emulators behind ptys:
hil_tests/test_hal_contract_serial.py.
"""

from __future__ import annotations

from contextlib import ExitStack
from numbers import Integral
from typing import Callable


from firmware_logic import fixedpoint as fx
from firmware_logic import hal as H
from firmware_logic import messages as msg
from firmware_logic.scripted import ScriptHal
from sim_backend import kernel
from sim_backend.batch.body import BatchBody
from sim_backend.batch.soa import BatchArrays
from sim_backend.engine import Engine
from sim_backend.scenario import validate
from sim_backend.world import World

HAL_METHODS = [n for n in vars(H.Hal) if not n.startswith("_")]
UP_KINDS = [m[0] for m in msg.MESSAGES if m[2] == msg.UP]


class HalContract:
    """The clauses; a subclass sets make() -> (hal, tick) where tick() ends
    the current tick (intents applied, messages exchanged)."""

    CANNOT: dict[str, str] = {}
    stack: ExitStack | None = None      # a body on a device: closed after each test

    def make(self) -> tuple[H.Hal, Callable[[], None]]:
        raise NotImplementedError

    def teardown_method(self, method: object) -> None:
        if self.stack is not None:
            self.stack.close()
            self.stack = None

    def _unless(self, clause: str) -> bool:
        reason = self.CANNOT.get(clause)
        if reason is not None:
            assert len(reason) > 10, f"{clause}: a body that cannot must say why"
            return False
        return True

    def test_every_method_is_there(self) -> None:
        hal, _ = self.make()
        for name in HAL_METHODS:
            assert callable(getattr(hal, name)), name
            assert getattr(type(hal), name) is not getattr(H.Hal, name), \
                f"{type(hal).__name__}.{name} is the base's NotImplementedError"

    def test_senses_answer_small_ints_in_range(self) -> None:
        hal, _ = self.make()
        assert isinstance(hal.x(), Integral) and isinstance(hal.y(), Integral)
        for h in range(0, 360, 15):
            assert hal.probe(h) in (H.NOTHING, H.OBJECT, H.CLAIMED, H.ROBOT, H.WALL)
            v = hal.field_ahead(h)
            assert isinstance(v, Integral) and v >= 0
        v = hal.field_here()
        assert isinstance(v, Integral) and v >= 0
        u = hal.uphill()
        assert u == -1 or (u % 45 == 0 and 0 <= u < 360)
        assert hal.holding() in (0, 1)

    def test_recv_on_an_empty_inbox_is_0_and_leaves_the_buffer(self) -> None:
        hal, _ = self.make()
        if not self._unless("empty inbox"):
            return
        buf = [11, 22, 33, 44, 55, 66]
        assert hal.recv(buf) == 0
        assert buf == [11, 22, 33, 44, 55, 66]

    def test_every_report_kind_can_be_sent(self) -> None:
        hal, tick = self.make()
        for kind in UP_KINDS:
            args = [1] * 6
            hal.send(kind, *args)
        hal.beacon(1)
        hal.beacon(0)
        tick()

    def test_forward_on_a_free_heading_moves_about_a_patch(self) -> None:
        hal, tick = self.make()
        if not self._unless("forward"):
            return
        free = [h for h in range(0, 360, 45) if hal.probe(h) == H.NOTHING]
        assert free, "no free heading to test on: fix the body's set-up"
        h = free[0]
        x0, y0 = hal.x(), hal.y()
        hal.forward(h, fx.ONE)
        tick()
        dx, dy = hal.x() - x0, hal.y() - y0
        assert abs(dx - fx.dx(h, fx.ONE)) <= fx.ONE // 8
        assert abs(dy - fx.dy(h, fx.ONE)) <= fx.ONE // 8

    def test_a_beacon_on_makes_a_field_here(self) -> None:
        hal, tick = self.make()
        if not self._unless("beacon field"):
            return
        before = hal.field_here()
        hal.beacon(1)
        tick()
        assert hal.field_here() > before


SCENARIO = {"agents": 3, "objectX": 5, "objectY": 5, "objectWeight": 1.0}


def placed(w: World) -> World:
    """Robot 1 at the origin, the others 6 patches away: every heading free."""
    w.xs[:] = [0, 6 * fx.ONE, -6 * fx.ONE]
    w.ys[:] = [0, 0, 0]
    w.recount()
    return w


class TestSimBody(HalContract):
    def make(self):
        e = Engine(validate(SCENARIO), 1)
        placed(e.world)
        body = e.bodies[0]
        body.reset_intents()

        def tick():
            e._apply()
            e.exchange()
            body.reset_intents()
        return body, tick


class TestBatchBody(HalContract):
    def make(self):
        arrays = BatchArrays([placed(World(validate(SCENARIO), 1))])
        body = BatchBody(*arrays.body_args())
        body.i = 0
        clock = [0]

        def tick():
            clock[0] += 1
            body.runs.tick[0] = clock[0]
            kernel.apply_tick(body.g, body.rb, body.runs, 0)
            body.rb.mv_on[0] = 0
            body.rb.claim[0] = -1
            body.rb.beacon_set[0] = -1
        return body, tick


class TestScriptHal(HalContract):
    CANNOT = {
        "empty inbox": "its inbox is a script: ACK, TRANSPORT and HALT arrive at seeded "
                       "random ticks, so no tick is known to be empty",
        "beacon field": "it has no world: its field readings are seeded numbers, "
                        "not a field a beacon raises",
    }

    def make(self):
        hal = ScriptHal(3, horizon=200)
        buf = [0] * 6

        def tick():
            while hal.recv(buf):      # the script counts ticks by the inbox drained
                pass
        tick()
        return hal, tick
