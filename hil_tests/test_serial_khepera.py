"""The Khepera II HAL (bridge/serial/khepera.py) against the emulator on a pty,
backed by the sim world, or against a real robot given --khepera-port PORT.

Tests that need to know the world (where the object is) run only on the
emulator; they are separate tests, not skips of the shared ones.
"""

from __future__ import annotations

import time

import pytest

from bridge.serial.khepera import KheperaBody, KheperaII
from firmware_logic import fixedpoint as fx
from firmware_logic.behaviours.thesis.robot import NOTHING, OBJECT
from sim_backend import scenario
from sim_backend.emulators.khepera import KheperaEmulator
from sim_backend.world import World

BAUD = 115200


def bar_world() -> World:
    sc = scenario.load("default").replace(agents=1, objectX=0, objectY=0, objectWeight=1.0)
    w = World(sc, 1)
    w.xs[0], w.ys[0] = -fx.ONE * 2, 0       # two patches west of the bar at (1..8, 0..1)
    w.recount()
    return w


@pytest.fixture
def world() -> World:
    return bar_world()


@pytest.fixture
def khepera(request: pytest.FixtureRequest, world: World):
    real = request.config.getoption("--khepera-port")
    if real:
        with KheperaII(real, request.config.getoption("--khepera-baud"), timeout=1.0) as k:
            yield k, None
        return
    # heading 90: facing east, toward the bar
    with KheperaEmulator(world, 0, baud=BAUD, heading=90) as emu:
        with KheperaII(emu.path, BAUD, timeout=0.5) as k:
            yield k, emu


def test_banner_and_version(khepera) -> None:
    k, _ = khepera
    bios, proto = k.version()
    assert bios[0].isdigit() and proto[0].isdigit()


def test_speeds_move_the_position_counters(khepera) -> None:
    k, _ = khepera
    k.reset_counters()
    assert k.counters() == (0, 0)
    k.set_speed(10, 10)
    time.sleep(0.2)
    k.set_speed(0, 0)
    left, right = k.counters()
    assert left > 50 and right > 50          # ~10 pulses per 10 ms for 0.2 s


def test_sensors_read_eight_ten_bit_values(khepera) -> None:
    k, _ = khepera
    for values in (k.proximity(), k.ambient()):
        assert len(values) == 8 and all(0 <= v <= 1023 for v in values)


def test_leds(khepera) -> None:
    k, _ = khepera
    k.led(1, 1)
    k.led(1, 0)
    k.led(1, 2)
    k.led(1, 2)


def test_body_touches_the_object_ahead_and_odometry_tracks_the_world(world: World) -> None:
    with KheperaEmulator(world, 0, baud=BAUD, heading=90) as emu, \
            KheperaII(emu.path, BAUD, timeout=0.5) as k:
        body = KheperaBody(k, 1, patch_mm=50.0, x_mm=-100.0, y_mm=0.0, heading=90,
                           cruise=40)
        assert body.probe(90) == NOTHING          # the bar is two patches east
        assert body.probe(270) == NOTHING
        body.forward(90, fx.ONE)                  # one patch east
        assert fx.patch(body.x()) == -1 and fx.patch(body.y()) == 0
        assert fx.patch(world.xs[0]) == -1
        assert abs(body.x() - world.xs[0]) < fx.ONE // 4
        assert body.probe(90) == NOTHING          # (0, 0) is free, (1, 0) is the bar
        body.forward(90, fx.ONE)
        assert body.probe(90) == OBJECT           # touching
        body.claim(90)
        assert body.holding() == 1
        # the beacon LED is the field source for the others
        before = world.field[world.idx(0, 0)]
        body.beacon(1)
        assert emu.leds[0] == 1 and world.field[world.idx(0, 0)] > before
        body.beacon(0)
        assert world.field[world.idx(0, 0)] == before


def test_body_turns_by_odometry(world: World) -> None:
    with KheperaEmulator(world, 0, baud=BAUD, heading=0) as emu, \
            KheperaII(emu.path, BAUD, timeout=0.5) as k:
        body = KheperaBody(k, 1, heading=0, x_mm=-100.0)
        body.turn_to(180)
        assert abs((body.theta - 180 + 180) % 360 - 180) < 6
        assert abs((emu.theta - body.theta + 180) % 360 - 180) < 3
