"""The HAL contract (tests/test_hal_contract.py) against the serial bodies:
the Khepera II and GoGo Board drivers talking to their emulators on ptys,
on a simulated clock (a tick is simulated time: no result depends on load).
"""

from __future__ import annotations

from contextlib import ExitStack

from bridge.serial.gogo import GoGoBoard, GoGoBody
from bridge.serial.khepera import KheperaBody, KheperaII
from hil_tests.test_serial_gogo import BAUD as GOGO_BAUD
from hil_tests.test_serial_gogo import FAST, bar_world
from sim_backend.emulators.gogo import GoGoEmulator
from sim_backend.emulators.khepera import KheperaEmulator
from sim_backend.emulators.worldrobot import SimClock
from tests.test_hal_contract import HalContract

TICK_S = 0.05
REAL_SENSES = ("a real robot's own LED raises no field its light sensors read as "
               "a field: the field comes from other robots' beacons")


class TestKheperaBody(HalContract):
    CANNOT = {"beacon field": REAL_SENSES}

    def make(self):
        self.stack = ExitStack()
        clock = SimClock()
        emu = self.stack.enter_context(KheperaEmulator(bar_world(), 0, baud=115200,
                                                       heading=90, clock=clock))
        k = self.stack.enter_context(KheperaII(emu.path, 115200, timeout=0.5))
        body = KheperaBody(k, 1, patch_mm=50.0, x_mm=-100.0, y_mm=0.0, heading=90,
                           cruise=40, tick_s=TICK_S)
        body.begin_tick()

        def tick():
            # a move takes several ticks on a real body: the tick ends when it is done
            body.settle(lambda: clock.advance(TICK_S), max_ticks=500)
            clock.advance(TICK_S)
            body.begin_tick()
        return body, tick


class TestGoGoBody(HalContract):
    CANNOT = {"beacon field": REAL_SENSES}

    def make(self):
        self.stack = ExitStack()
        world = bar_world()
        emu = self.stack.enter_context(GoGoEmulator(world, 0, baud=GOGO_BAUD, heading=90,
                                                    mm_s_per_level=FAST, clock=SimClock()))
        b = self.stack.enter_context(GoGoBoard(emu.path, GOGO_BAUD, timeout=0.5))
        body = GoGoBody(b, 1, patch_mm=50.0, mm_s_per_level=FAST, tick_s=TICK_S,
                        clock=emu.clock, x_mm=-100.0, heading=90, arena=world.w)
        body.begin_tick()

        def tick():
            body.settle(lambda: body.clock.sleep(TICK_S), max_ticks=500)
            body.clock.sleep(TICK_S)
            body.begin_tick()
        return body, tick
