"""The GoGo Board HAL (bridge/serial/gogo.py) against the emulator on a pty,
backed by the sim world, or against a real board given --gogo-port PORT.

The shared tests (protocol, sensors, motors, LED, wrong baud, the body's
set-up, beacon and a short turn) run on either. Tests that need to know the
world (where the object is) or inject faults into the line run only on the
emulator; they are separate tests, not skips of the shared ones.

On the emulator, time is a SimClock shared by the emulator and the body:
motors run exactly as long in the emulated world as the body believes,
however loaded the machine is, so the body's pose and the world's can be
compared tightly. No test sleeps and then asserts.
"""

from __future__ import annotations


import pytest

from bridge.serial.errors import ProtocolError, SerialLinkError, SerialPortLost, SerialTimeout
from bridge.serial.gogo import GoGoBoard, GoGoBody
from firmware_logic import fixedpoint as fx
from firmware_logic import messages as msg
from firmware_logic.hal import NOTHING, OBJECT, WALL
from firmware_logic.behaviours.thesis.robot import FIREFLY, HOLD, Robot
from sim_backend import scenario
from sim_backend.emulators.gogo import GoGoEmulator
from sim_backend.emulators.worldrobot import SimClock
from sim_backend.engine import InprocLink
from sim_backend.world import World

BAUD = 9600
FAST = 40.0           # mm/s per power level of the emulated robot (280 mm/s at 7)
TICK_S = 0.05


def bar_world(px: int = -2, py: int = 0) -> World:
    sc = scenario.load("default").replace(agents=1, objectX=0, objectY=0, objectWeight=1.0)
    w = World(sc, 1)
    w.xs[0], w.ys[0] = px * fx.ONE, py * fx.ONE     # the bar covers (1..8, 0..1)
    w.recount()
    return w


@pytest.fixture
def gogo_port(request: pytest.FixtureRequest):
    """(port, emulator or None): a real board's port, or an emulator's pty."""
    real = request.config.getoption("--gogo-port")
    if real:
        yield real, None
        return
    # facing east, two patches west of the bar
    with GoGoEmulator(bar_world(), 0, baud=BAUD, heading=90, mm_s_per_level=FAST,
                      clock=SimClock()) as emu:
        yield emu.path, emu


@pytest.fixture
def board(gogo_port):
    port, _ = gogo_port
    with GoGoBoard(port, BAUD, timeout=0.5) as b:
        yield b


def body_on(b: GoGoBoard, emu: GoGoEmulator | None, **kw) -> GoGoBody:
    opts = dict(patch_mm=50.0, mm_s_per_level=FAST, tick_s=TICK_S,
                clock=emu.clock if emu is not None else None)
    opts.update(kw)
    return GoGoBody(b, 1, **opts)


def next_tick(body: GoGoBody) -> None:
    """Let one tick's time pass (simulated on the emulator) and begin the next."""
    body.clock.sleep(TICK_S)
    body.begin_tick()


def finish(body: GoGoBody) -> int:
    """Run ticks until the body's motion ends, then start a fresh tick."""
    n = body.settle(lambda: body.clock.sleep(TICK_S), max_ticks=500)
    assert not body.busy(), body.phases
    next_tick(body)
    return n


# -- shared: emulator or a real board --------------------------------------------------


def test_ping_is_echoed_and_acknowledged(board: GoGoBoard) -> None:
    for _ in range(3):
        board.ping()
    assert board.retried == 0


def test_eight_sensor_ports_read_ten_bits_in_every_mode(board: GoGoBoard) -> None:
    for n in range(1, 9):
        for mode in (0, 1, 2):
            assert 0 <= board.sensor(n, mode) <= 1023


def test_motor_power_and_direction_commands(gogo_port, board: GoGoBoard) -> None:
    _, emu = gogo_port
    for ports in ("A", "B", "AB", "CD"):
        board.select(ports)
        for level in range(8):
            board.power(level)
    board.select("AB")
    board.power(2)
    board.thisway()
    board.thatway()
    board.reverse()
    board.on()
    board.coast()
    board.on()
    board.off()
    if emu is not None:
        assert emu.selected == 3 and emu.motor_power[1] == emu.motor_power[2] == 2
        assert emu.motor_power[4] == 7 and emu.motor_dir[1] == 1 and not emu.motor_on[1]


def test_led_and_beep(gogo_port, board: GoGoBoard) -> None:
    _, emu = gogo_port
    board.led(True)
    board.beep()
    board.led(False)
    if emu is not None:
        assert emu.beeps == 1 and emu.led == 0


def test_wrong_baud_is_a_clear_error_and_leaves_the_board_usable(gogo_port) -> None:
    port, emu = gogo_port
    with GoGoBoard(port, 19200, timeout=0.3, quiet=0.05) as b:
        # a real UART may drop the garbled bytes instead of echoing garbage
        err = ProtocolError if emu is not None else (ProtocolError, SerialTimeout)
        with pytest.raises(err, match="9600 baud"):
            b.ping()
    with GoGoBoard(port, BAUD, timeout=0.5) as b:
        b.ping()


def test_body_setup_beacon_and_a_short_turn(gogo_port, board: GoGoBoard) -> None:
    _, emu = gogo_port
    body = body_on(board, emu, heading=90)
    body.begin_tick()
    assert body.probe(90) in (NOTHING, OBJECT)
    assert 0 <= body.field_here() <= 800 // 40
    body.beacon(1)
    body.beacon(0)
    body.turn_to(120)
    finish(body)
    # the body's own estimate: ran at least what it planned, at most one
    # wire-time compensation off (on a real board, host jitter adds to it)
    assert abs(body.theta - 120) < 1
    body.turn_to(90)
    finish(body)
    if emu is not None:
        assert emu.led == 0 and emu.beacon_src is None
        # on the shared clock the world turned exactly as long as the body timed
        assert abs((emu.theta - body.theta + 180) % 360 - 180) < 1e-6
        assert abs(body.theta - 90) < 1e-6
        assert not emu.motor_on[1] and not emu.motor_on[2]


# -- emulator only: the world, and faults injected into the line -------------------------


def emulated(world: World, **kw) -> GoGoEmulator:
    opts = dict(baud=BAUD, mm_s_per_level=FAST, clock=SimClock())
    opts.update(kw)
    return GoGoEmulator(world, 0, **opts)


def test_body_touches_the_bar_and_dead_reckoning_tracks_the_world() -> None:
    world = bar_world()
    with emulated(world, heading=90) as emu, GoGoBoard(emu.path, BAUD) as b:
        body = body_on(b, emu, x_mm=-100.0, heading=90, arena=world.w)
        body.begin_tick()
        assert body.probe(90) == NOTHING          # the bar is two patches east
        assert body.probe(270) == NOTHING and body.probe(0) == NOTHING
        body.forward(90, fx.ONE)                  # one patch east
        finish(body)
        assert fx.patch(body.x()) == -1 and fx.patch(body.y()) == 0
        assert fx.patch(world.xs[0]) == -1
        assert abs(body.x() - world.xs[0]) <= 1   # Q8 rounding only: same clock
        assert abs(body.y() - world.ys[0]) <= 1
        assert body.probe(90) == NOTHING          # (0, 0) is free, (1, 0) is the bar
        body.forward(90, fx.ONE)
        finish(body)
        assert body.probe(90) == OBJECT           # the front switch is closed
        assert body.probe(0) == NOTHING           # (0, 1) is free
        body.claim(90)
        finish(body)
        assert body.holding() == 1
        before = world.field[world.idx(0, 0)]
        body.beacon(1)                            # the user LED is the field source
        assert emu.led == 1 and world.field[world.idx(0, 0)] > before
        body.beacon(0)
        assert world.field[world.idx(0, 0)] == before
        # a turn in place, then the left switch faces the bar
        body.turn_to(0)
        finish(body)
        assert abs((emu.theta - body.theta + 180) % 360 - 180) < 1e-6
        assert body.probe(90) == OBJECT and body.probe(0) == NOTHING


def test_an_action_returns_at_once_and_ends_on_a_later_tick() -> None:
    world = bar_world()
    with emulated(world, heading=90) as emu, GoGoBoard(emu.path, BAUD) as b:
        body = body_on(b, emu, x_mm=-100.0, heading=90)
        body.begin_tick()
        body.forward(90, fx.ONE)                  # no turn needed: straight to driving
        # started, not carried out: the motors run, no simulated time passed
        assert body.busy() and emu.motor_on[1] and emu.motor_on[2]
        assert body.clock.now() == 0.0 and body.x_mm == -100.0
        ticks = 0
        while body.busy():
            next_tick(body)
            ticks += 1
            assert ticks < 50
        # 50 mm at 280 mm/s is 0.179 s: still on at 0.05 and 0.10; at 0.15 the end
        # falls before the next tick, so that tick waits the last 0.029 s out
        assert ticks == 3
        assert not emu.motor_on[1] and not emu.motor_on[2]
        assert body.clock.now() == pytest.approx(50.0 / (7 * FAST))
        assert body.x_mm == pytest.approx(-50.0) and emu.x_mm == pytest.approx(-50.0)


def test_one_tick_reads_each_sensor_port_once() -> None:
    world = bar_world()
    with emulated(world, heading=90) as emu, GoGoBoard(emu.path, BAUD) as b:
        body = body_on(b, emu, x_mm=-100.0, heading=90, light_ports={0: 5, 180: 6})
        for _ in range(2):
            next_tick(body)
            before = emu.commands
            for h in range(0, 360, 45):
                body.probe(h)
                body.field_ahead(h)
            body.field_here()
            body.uphill()
            body.x()
            body.y()
            # four touch switches and two light sensors, each read once
            assert emu.commands - before == 6


def world_edge() -> int:
    return scenario.load("default").worldSize


def test_walls_mirrored_motors_and_carry() -> None:
    # right motor mounted mirrored: forward is `thatway` on B, on both sides
    world = bar_world(-world_edge(), 0)
    with emulated(world, heading=270, right_forward="thatway") as emu, \
            GoGoBoard(emu.path, BAUD) as b:
        body = body_on(b, emu, x_mm=-world.w * 50.0, heading=270, arena=world.w,
                       right_forward="thatway")
        body.begin_tick()
        assert body.probe(270) == WALL            # the arena's west edge
        body.forward(0, fx.ONE)                   # turn north, drive one patch
        finish(body)
        assert fx.patch(world.ys[0]) == 1 and fx.patch(body.y()) == 1
        assert abs(body.x() - world.xs[0]) <= 1
        assert body.probe(270) == WALL
        body.carry(1, 0)                          # the centralised phase's step: east
        finish(body)
        assert fx.patch(world.xs[0]) == -world.w + 1 and fx.patch(world.ys[0]) == 1
        assert fx.patch(body.x()) == -world.w + 1 and abs(body.theta - 90) < 1e-6


def test_firmware_on_a_gogo_robot_touches_and_reports() -> None:
    # the unchanged firmware FSM, its body a GoGo robot next to the bar
    world = bar_world(0, 0)
    link = InprocLink([1])
    with emulated(world, heading=0) as emu, GoGoBoard(emu.path, BAUD) as b:
        body = body_on(b, emu, link=link, heading=0, arena=world.w)
        robot = Robot(1, 7, FIREFLY, 45, 2, 100)
        steps = ticks = 0
        while robot.state != HOLD:
            assert ticks < 200, (robot.state, steps)
            steps += body.tick(robot)             # stepped only while the body is idle
            body.clock.sleep(TICK_S)
            ticks += 1
        assert steps == 2 and ticks > steps       # the claim's turn took ticks of its own
        assert emu.led == 1 and emu.beacon_src == (0, 0)
        assert abs((emu.theta - 90 + 180) % 360 - 180) < 1e-6  # turned to face the bar
        sent = link.poll(0)
        touches = [f for n, k, f in sent if k == msg.TOUCH]
        assert touches and touches[0][:5] == (1, 0, 0, 1, 0)  # seq, robot (0,0), bar (1,0)


def test_one_light_sensor_follows_the_gradient_it_drove_along() -> None:
    world = bar_world(-3, -6)
    world.signal(-3, -1)                          # a beacon five patches north
    with emulated(world, heading=0) as emu, GoGoBoard(emu.path, BAUD) as b:
        body = body_on(b, emu, x_mm=-150.0, y_mm=-300.0, heading=0)
        body.begin_tick()
        assert body.field_ahead(0) > 0 and body.uphill() == -1     # no way known yet
        assert emu.reading(5) == 800 - 40 * world.field[world.idx(-3, -5)]
        body.forward(0, fx.ONE)
        finish(body)
        assert body.uphill() == 0                 # brighter after driving north
        body.forward(180, fx.ONE)
        finish(body)
        assert body.uphill() == -1                # darker after driving south


def test_dead_reckoning_cannot_see_a_wheel_pushing_against_the_bar() -> None:
    # the documented limitation: no encoders, so the pose is what was commanded
    world = bar_world(0, 0)
    with emulated(world, heading=90) as emu, GoGoBoard(emu.path, BAUD) as b:
        body = body_on(b, emu, heading=90)
        body.begin_tick()
        body.drive(50.0)
        finish(body)
        assert fx.patch(world.xs[0]) == 0 and emu.x_mm == 0.0    # stuck at the bar
        assert fx.patch(body.x()) == 1                           # believes it moved


def test_body_rides_out_garbage_and_truncation_and_fails_clearly_on_a_lost_port() -> None:
    world = bar_world()
    with emulated(world, heading=90) as emu, \
            GoGoBoard(emu.path, BAUD, timeout=0.2, quiet=0.05) as b:
        # two light sensors (front, rear): the field is compared across them
        body = body_on(b, emu, x_mm=-100.0, heading=90, light_ports={0: 5, 180: 6})
        body.begin_tick()
        assert body.uphill() == -1                # no field anywhere yet
        next_tick(body)
        emu.garbage_next = b"\x00\x13\x37"
        emu.noise_next = b"\xfe\x55"
        assert body.probe(90) == NOTHING
        emu.truncate_next = 2                     # the move's first command (select A)
        body.forward(90, fx.ONE)                  # loses its ACK and is retried
        finish(body)
        assert b.retried == 1 and b.junk == 5
        assert abs(body.x() - world.xs[0]) <= 1
        assert not emu.motor_on[1] and not emu.motor_on[2]
        # unplugged while driving: typed errors, never a raw termios.error
        body.forward(90, fx.ONE)
        assert body.busy() and emu.motor_on[1]
        emu.vanish()
        with pytest.raises(SerialPortLost):         # when the tick that stops it comes
            for _ in range(10):
                next_tick(body)
        for _ in range(2):                        # and every tick while it is gone
            with pytest.raises(SerialPortLost) as err:
                next_tick(body)
            assert isinstance(err.value, SerialPortLost) and "\n" not in str(err.value)
        assert not body.busy()                    # the move is lost with the port
        with pytest.raises(SerialLinkError):
            body.forward(90, fx.ONE)
        assert body.x_mm == pytest.approx(-50.0)  # a failed move is not counted
        emu.come_back()
        next_tick(body)                           # the board is set up again, motors off
        assert not emu.motor_on[1] and not emu.motor_on[2] and b.reopened == 1
        # the motors ran on while it was unplugged, unseen: dead reckoning lost
        # track (documented), so put the body where the robot is, and go on
        body.x_mm, body.y_mm, body.theta = emu.x_mm, emu.y_mm, emu.theta
        for _ in range(3):
            if body.probe(90) == OBJECT:
                break
            body.forward(90, fx.ONE)
            finish(body)
        assert body.probe(90) == OBJECT and fx.patch(world.xs[0]) == 0
