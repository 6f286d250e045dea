"""The Khepera II HAL (bridge/serial/khepera.py) against the emulator on a pty,
backed by the sim world, or against a real robot given --khepera-port PORT.

Tests that need to know the world (where the object is) run only on the
emulator; they are separate tests, not skips of the shared ones.

On the emulator time is a SimClock shared by the emulator and the body: the
test advances it one tick at a time, so how far a wheel turns between two
commands is fixed, however loaded the machine is. No test sleeps and then
asserts; they wait on conditions.
"""

from __future__ import annotations

import time
from typing import Callable

import pytest

from bridge.serial.errors import SerialPortLost, SerialTimeout
from bridge.serial.khepera import KheperaBody, KheperaII
from firmware_logic import fixedpoint as fx
from firmware_logic.hal import NOTHING, OBJECT
from sim_backend import scenario
from sim_backend.emulators.khepera import KheperaEmulator
from sim_backend.emulators.worldrobot import SimClock
from sim_backend.world import World

BAUD = 115200
TICK_S = 0.05


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
    with KheperaEmulator(world, 0, baud=BAUD, heading=90, clock=SimClock()) as emu:
        with KheperaII(emu.path, BAUD, timeout=0.5) as k:
            yield k, emu


def wait_for(cond: Callable[[], bool], emu: KheperaEmulator | None,
             limit_s: float = 5.0, step_s: float = 0.01) -> None:
    """Let time pass until cond() holds: simulated time on the emulator,
    real time (bounded) on a robot."""
    waited = 0.0
    deadline = time.monotonic() + limit_s
    while not cond():
        if emu is not None:
            assert waited < limit_s, "condition not met after %.2f simulated s" % waited
            emu.clock.advance(step_s)
            waited += step_s
        else:
            assert time.monotonic() < deadline, "condition not met within %.1f s" % limit_s
            time.sleep(step_s)


def finish(body: KheperaBody, clock: SimClock) -> int:
    """Run ticks until the body's motion ends, then start a fresh tick."""
    n = body.settle(lambda: clock.advance(TICK_S), max_ticks=500)
    assert not body.busy() and body.abandoned == 0, (n, body.phases)
    clock.advance(TICK_S)
    body.begin_tick()
    return n


# -- shared: emulator or a real robot -----------------------------------------------------


def test_banner_and_version(khepera) -> None:
    k, _ = khepera
    bios, proto = k.version()
    assert bios[0].isdigit() and proto[0].isdigit()


def test_speeds_move_the_position_counters(khepera) -> None:
    k, emu = khepera
    k.reset_counters()
    assert k.counters() == (0, 0)
    k.set_speed(10, 10)
    wait_for(lambda: min(k.counters()) > 50, emu)     # ~10 pulses per 10 ms
    k.set_speed(0, 0)
    stopped = k.counters()
    if emu is not None:
        emu.clock.advance(0.5)
        assert k.counters() == stopped                # stopped means stopped


def test_sensors_read_eight_ten_bit_values(khepera) -> None:
    k, _ = khepera
    for values in (k.proximity(), k.ambient()):
        assert len(values) == 8 and all(0 <= v <= 1023 for v in values)


def test_leds_on_off_and_toggle(khepera) -> None:
    """L,n,act: on, off, then toggle (2) twice. Each command waits for the
    robot's acknowledgement; on the emulator the LED's state is checked too
    (a real robot's LED cannot be read back over the serial protocol)."""
    k, emu = khepera
    for act, lit in ((1, 1), (0, 0), (2, 1), (2, 0)):
        k.led(1, act)
        if emu is not None:
            assert emu.leds[1] == lit, (act, emu.leds)


# -- emulator only: the world, and faults --------------------------------------------------


def test_body_touches_the_object_ahead_and_odometry_tracks_the_world(world: World) -> None:
    clock = SimClock()
    with KheperaEmulator(world, 0, baud=BAUD, heading=90, clock=clock) as emu, \
            KheperaII(emu.path, BAUD, timeout=0.5) as k:
        body = KheperaBody(k, 1, patch_mm=50.0, x_mm=-100.0, y_mm=0.0, heading=90,
                           cruise=40, tick_s=TICK_S)
        body.begin_tick()
        assert body.probe(90) == NOTHING          # the bar is two patches east
        assert body.probe(270) == NOTHING
        body.forward(90, fx.ONE)                  # one patch east
        finish(body, clock)
        assert fx.patch(body.x()) == -1 and fx.patch(body.y()) == 0
        assert fx.patch(world.xs[0]) == -1
        assert abs(body.x() - world.xs[0]) < fx.ONE // 16
        assert body.probe(90) == NOTHING          # (0, 0) is free, (1, 0) is the bar
        body.forward(90, fx.ONE)
        finish(body, clock)
        assert body.probe(90) == OBJECT           # touching
        body.claim(90)
        finish(body, clock)
        assert body.holding() == 1
        # the beacon LED is the field source for the others
        before = world.field[world.idx(0, 0)]
        body.beacon(1)
        assert emu.leds[0] == 1 and world.field[world.idx(0, 0)] > before
        body.beacon(0)
        assert world.field[world.idx(0, 0)] == before


def test_body_turns_by_odometry_over_ticks(world: World) -> None:
    clock = SimClock()
    with KheperaEmulator(world, 0, baud=BAUD, heading=0, clock=clock) as emu, \
            KheperaII(emu.path, BAUD, timeout=0.5) as k:
        body = KheperaBody(k, 1, heading=0, x_mm=-100.0, tick_s=TICK_S)
        body.begin_tick()
        body.turn_to(180)
        ticks = finish(body, clock)
        # a half turn at 20 pulses / 10 ms takes ~10 ticks of 50 ms, then slows down
        assert 10 <= ticks <= 40
        assert abs((body.theta - 180 + 180) % 360 - 180) < body.turn_tolerance
        assert abs((emu.theta - body.theta + 180) % 360 - 180) < 0.5
        assert emu.speed == [0, 0]


def test_an_action_returns_at_once_and_progresses_on_later_ticks(world: World) -> None:
    clock = SimClock()
    with KheperaEmulator(world, 0, baud=BAUD, heading=90, clock=clock) as emu, \
            KheperaII(emu.path, BAUD, timeout=0.5) as k:
        body = KheperaBody(k, 1, x_mm=-100.0, heading=90, tick_s=TICK_S)
        body.begin_tick()
        body.probe(90)
        sent = emu.commands
        body.forward(90, fx.ONE)
        # started, not carried out: one `D`, no simulated time passed
        assert emu.commands == sent + 1 and clock.now() == 0.0
        assert body.busy() and emu.speed[0] > 0 and emu.speed == [emu.speed[0]] * 2
        xs = []
        while body.busy():
            clock.advance(TICK_S)
            before = emu.commands
            body.begin_tick()
            assert emu.commands - before <= 2     # one `H`, at most one `D`
            xs.append(body.x_mm)
            assert len(xs) < 100
        assert len(xs) >= 3 and xs == sorted(xs)   # it got there over several ticks
        assert abs(body.x_mm - -50.0) < 1.0


def test_one_tick_reads_each_sensor_once(world: World) -> None:
    clock = SimClock()
    with KheperaEmulator(world, 0, baud=BAUD, heading=90, clock=clock) as emu, \
            KheperaII(emu.path, BAUD, timeout=0.5) as k:
        body = KheperaBody(k, 1, x_mm=-100.0, heading=90, tick_s=TICK_S)
        for _ in range(2):
            clock.advance(TICK_S)
            body.begin_tick()
            before = emu.commands
            for h in range(0, 360, 45):
                body.probe(h)
                body.field_ahead(h)
            body.field_here()
            body.uphill()
            body.holding()
            body.x()
            body.y()
            assert emu.commands - before == 3     # H, N and O, once each


def test_unplugged_during_a_move_raises_typed_errors_then_goes_on(world: World) -> None:
    clock = SimClock()
    with KheperaEmulator(world, 0, baud=BAUD, heading=90, clock=clock) as emu, \
            KheperaII(emu.path, BAUD, timeout=0.2) as k:
        body = KheperaBody(k, 1, x_mm=-100.0, heading=90, tick_s=TICK_S)
        body.begin_tick()
        body.forward(90, fx.ONE)
        clock.advance(TICK_S)
        body.begin_tick()
        emu.vanish()
        for _ in range(3):                        # every tick while it is gone
            clock.advance(TICK_S)
            with pytest.raises(SerialPortLost) as err:
                body.begin_tick()
            assert isinstance(err.value, SerialTimeout)
            assert "\n" not in str(err.value)
        with pytest.raises(SerialPortLost):
            body.probe(90)
        emu.come_back()
        assert body.busy()                        # the encoders kept count: go on
        finish(body, clock)
        assert k.reopened == 1
        # the robot kept driving while unplugged; odometry saw all of it
        assert abs(body.x() - world.xs[0]) < fx.ONE // 16
