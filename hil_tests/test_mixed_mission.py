"""A mission with one real body and a simulated swarm (bridge/mission.py),
end to end: body URL -> registry -> driver on a pty -> emulated robot in its
own bench world; the host coordinator collects every touch exactly once.

On the emulators the clock is a SimClock shared by the emulator, the body
and the mission's pacing: ticks pass in simulated time, so no result depends
on how loaded the machine is; the tests wait on conditions with a bound in
ticks, never on sleeps.

Real ports: `--khepera-port PORT [--khepera-baud N]` and `--gogo-port PORT`
run the same missions on a robot put down at patch (0, 0) facing east, with
the object's west end (the bar, `objectX=0 objectY=0`: patches 1..8 x 0..1)
touching its front; the mission then runs on the wall clock.
"""

from __future__ import annotations

from collections import Counter

import pytest

from bridge.bodies import parse_body_url
from bridge.mission import MixedMission
from firmware_logic import fixedpoint as fx
from sim_backend import scenario
from sim_backend.emulators.gogo import GoGoEmulator
from sim_backend.emulators.khepera import KheperaEmulator
from sim_backend.emulators.worldrobot import SimClock
from sim_backend.world import World

SEED = 2
REAL = 1                     # the node that is a real body
TICK_S = 0.05


def mission_scenario():
    # weight = all six robots: the mission runs on for the whole test, so
    # the test sees every touch and every retransmission of the whole run
    return scenario.load("default").replace(agents=6, objectX=0, objectY=0,
                                            objectWeight=6.0, maxTicks=5000)


def bench_world(sc) -> World:
    """The emulated robot's physical world: the same object, and only the
    real robot (a real robot does not touch simulated ones)."""
    w = World(sc, SEED)
    w.xs, w.ys = [0], [0]    # put down at patch (0, 0), facing east: the bar is ahead
    w.recount()
    return w


def pending(m: MixedMission) -> int:
    return m.hosts[REAL].fsm.pending


def touched_and_acked(m: MixedMission) -> bool:
    c = m.engine.coordinator
    return any(t.node == REAL for t in c.touches) and pending(m) == 0


def run_mission(url: str, clock: SimClock | None) -> tuple[MixedMission, dict]:
    sc = mission_scenario()
    with MixedMission(sc, SEED, {REAL: parse_body_url(url)}, tick_s=TICK_S,
                      clock=clock) as m:
        assert m.start_poses()[REAL][:2] == (0, 0)
        m.run(max_ticks=600, until=touched_and_acked)
        assert touched_and_acked(m), (
            "no acknowledged touch from the real robot after %d ticks; touches %r"
            % (m.engine.tick, [(t.node, t.seq) for t in m.engine.coordinator.touches]))
        # go on well past the ACK: a retransmission or a second report would show
        m.run(max_ticks=m.engine.tick + 150)
        result = m.run(max_ticks=m.engine.tick)
        return m, m.summary(result)


def check_exactly_once(m: MixedMission, s: dict) -> None:
    c = m.engine.coordinator
    keys = Counter((t.node, t.seq) for t in c.touches)
    assert all(n == 1 for n in keys.values()), keys
    assert s["real_touches"] == {str(REAL): 1}
    t = next(t for t in c.touches if t.node == REAL)
    # reported from where it was put down, the segment east of it
    assert (t.rx, t.ry, t.sx, t.sy) == (0, 0, 1, 0)
    # the real robot holds the segment in the sim world too, and sits there
    w = m.engine.world
    assert w.owner[w.idx(1, 0)] == REAL
    assert (fx.patch(w.xs[REAL - 1]), fx.patch(w.ys[REAL - 1])) == (0, 0)
    assert s["real_failed_ticks"] == {str(REAL): 0}
    # its beacon LED is a field source for the simulated robots
    i = REAL - 1
    assert (w.beacon_on[i], w.bsx[i], w.bsy[i]) == (1, 0, 0)


PUT_DOWN = "x=0&y=0&heading=90"


def emulated_or_real(request, scheme: str, real: str | None, options: str, emulator_cls,
                     baud: int):
    """Run the mission on the real port when given, else on an emulator on a
    pty sharing a SimClock with the mission; returns (mission, summary, emu)."""
    if real:
        m, s = run_mission(f"{scheme}://{real}?{options}{PUT_DOWN}", None)
        check_exactly_once(m, s)
        return m, s, None
    clock = SimClock()
    with emulator_cls(bench_world(mission_scenario()), 0, baud=baud, heading=90,
                      clock=clock) as emu:
        m, s = run_mission(f"{scheme}://{emu.path}?baud={baud}&{PUT_DOWN}", clock)
        check_exactly_once(m, s)
    return m, s, emu


def test_khepera_and_a_simulated_swarm_report_each_touch_once(request) -> None:
    baud = request.config.getoption("--khepera-baud")
    m, s, emu = emulated_or_real(request, "khepera", request.config.getoption("--khepera-port"),
                                 f"baud={baud}&", KheperaEmulator, 115200)
    if emu is None:
        return
    assert emu.leds[0] == 0 and emu.speed == [0, 0]    # left dark and stopped
    assert s["bodies"][str(REAL)].startswith("Khepera II on ")
    # the simulated robots went on moving next to it
    start = World(mission_scenario(), SEED)
    assert m.engine.tick > 150
    assert any((a, b) != (c, d) for a, b, c, d in
               zip(start.xs[1:], start.ys[1:], m.engine.world.xs[1:], m.engine.world.ys[1:]))


def test_gogo_and_a_simulated_swarm_report_each_touch_once(request) -> None:
    m, s, emu = emulated_or_real(request, "gogo", request.config.getoption("--gogo-port"),
                                 "", GoGoEmulator, 9600)
    if emu is not None:
        assert not any(emu.motor_on.values()) and emu.led == 0   # left stopped and dark
        assert s["bodies"][str(REAL)].startswith("GoGo Board on ")


def test_a_real_robot_put_down_on_a_simulated_one_is_refused() -> None:
    from bridge.bodies import BodyURLError
    sc = mission_scenario()
    w = World(sc, SEED)
    other = (fx.patch(w.xs[3]), fx.patch(w.ys[3]))
    with KheperaEmulator(None, 0, baud=115200, clock=SimClock()) as emu:
        url = f"khepera://{emu.path}?baud=115200&x={other[0]}&y={other[1]}"
        with pytest.raises(BodyURLError, match="taken by simulated robot 4"):
            MixedMission(sc, SEED, {REAL: parse_body_url(url)}, clock=SimClock())


def test_the_mission_command_on_an_emulated_khepera(capsys) -> None:
    """`touchswarm mission --body 1=khepera://PTY...` end to end. The CLI runs
    on the wall clock (as on a bench); the robot is put down touching the
    bar, so its claim needs no motion and the outcome does not depend on
    how long a tick really took."""
    import json

    from bridge.cli import main as cli_main
    sc = mission_scenario()
    with KheperaEmulator(bench_world(sc), 0, baud=115200, heading=90) as emu:
        url = f"khepera://{emu.path}?baud=115200&x=0&y=0&heading=90"
        code = cli_main(["mission", "--body", f"{REAL}={url}", "--json", "--seed", str(SEED),
                         "--robots", "6", "--set", "objectX=0", "--set", "objectY=0",
                         "--set", "objectWeight=6.0", "--max-ticks", "80", "--tick-ms", "5"])
        out, err = capsys.readouterr()
    assert code == 1, err                        # not delivered in 80 ticks: exit 1
    s = json.loads(out)
    assert s["ticks"] == 80 and not s["delivered"]
    assert s["real_touches"] == {str(REAL): 1} and s["real_failed_ticks"] == {str(REAL): 0}
    assert [0, 0] in s["touches"] and [1, 0] in s["segments"]
    assert f"robot {REAL}: Khepera II on {emu.path} at 115200 baud, put down at patch (0, 0) " \
           "facing 90 degrees" in err


def test_a_moving_khepera_is_where_its_odometry_says_in_the_sim_world() -> None:
    """Put down away from the object, the real robot searches like the
    others: its place in the sim world follows its odometry tick by tick
    (within 1/8 patch of where the emulated robot really is), and the
    simulated robots see it there."""
    sc = mission_scenario()
    bench = World(sc, SEED)
    bench.xs, bench.ys = [-6 * fx.ONE], [6 * fx.ONE]
    bench.recount()
    clock = SimClock()
    with KheperaEmulator(bench, 0, baud=115200, heading=0, clock=clock) as emu:
        url = f"khepera://{emu.path}?baud=115200&x=-6&y=6&heading=0"
        with MixedMission(sc, SEED, {REAL: parse_body_url(url)}, tick_s=TICK_S,
                          clock=clock) as m:
            w = m.engine.world
            far = 0
            for _ in range(400):
                m.run(max_ticks=m.engine.tick + 1)
                assert abs(w.xs[REAL - 1] - bench.xs[0]) < fx.ONE // 8
                assert abs(w.ys[REAL - 1] - bench.ys[0]) < fx.ONE // 8
                assert w.occ[w.idx(fx.patch(w.xs[REAL - 1]), fx.patch(w.ys[REAL - 1]))] >= 1
                far = max(far, abs(bench.xs[0] + 6 * fx.ONE) + abs(bench.ys[0] - 6 * fx.ONE))
            assert far >= 2 * fx.ONE                 # it went somewhere
            assert m.hosts[REAL].steps < m.engine.tick   # moves took more than a tick
            assert m.hosts[REAL].failed_ticks == 0


def test_a_micropython_robot_joins_a_simulated_swarm(micropython_device) -> None:
    """mpy://PORT: the firmware deployed on MicroPython (the unix port behind
    a pty) runs its own ticks; the mission serves its senses from the sim
    world through the tether and its reports reach the same coordinator as
    the simulated robots'. Wall clock (the board ticks on its own); bounded
    in ticks, waiting on the touch, never on a sleep."""
    from bridge.serial.deploy import Deployer
    dev = micropython_device
    sc = mission_scenario()
    Deployer(dev.path).deploy({"NODE": REAL, "SEED": SEED, "MAX_TICKS": 5000, "LINGER": 2}, sc)
    Deployer(dev.path).start()
    with MixedMission(sc, SEED, {REAL: parse_body_url(f"mpy://{dev.path}?x=0&y=0")},
                      tick_s=0.02) as m:
        c = m.engine.coordinator
        m.run(max_ticks=1500, until=lambda mm: any(t.node == REAL for t in c.touches))
        assert any(t.node == REAL for t in c.touches), (m.engine.tick, c.rejected)
        # the board sees its ACK and stops retransmitting; a duplicate would count
        m.run(max_ticks=m.engine.tick + 100)
        s = m.summary(m.run(max_ticks=m.engine.tick))
    keys = Counter((t.node, t.seq) for t in c.touches)
    assert all(n == 1 for n in keys.values()), keys
    assert s["real_touches"] == {str(REAL): 1}
    t = next(t for t in c.touches if t.node == REAL)
    w = m.engine.world
    # a bar segment next to where it stood; held in the world by the engine's rule
    assert (t.sx, t.sy) in w.object_cells and abs(t.sx - t.rx) + abs(t.sy - t.ry) == 1
    assert w.owner[w.idx(t.sx, t.sy)] == REAL
    assert s["bodies"][str(REAL)].startswith("MicroPython robot on ")


def test_mission_cli_with_a_micropython_body_prints_its_summary(micropython_device, capsys):
    """`touchswarm mission --body 1=mpy://PORT` in text: the tethered board's
    line (its touches; it has no host-stepped failed ticks) after the
    summary, not a KeyError."""
    from bridge.cli import main
    from bridge.serial.deploy import Deployer
    dev = micropython_device
    Deployer(dev.path).deploy({"NODE": REAL, "SEED": SEED, "MAX_TICKS": 5000,
                               "LINGER": 2})
    Deployer(dev.path).start()
    rc = main(["mission", "--body", f"{REAL}=mpy://{dev.path}?x=0&y=0", "--robots", "6",
               "--seed", str(SEED), "--tick-ms", "20", "--max-ticks", "60"])
    assert rc in (0, 1)
    out = capsys.readouterr().out
    line = [ln for ln in out.splitlines() if ln.startswith(f"  robot {REAL} ")]
    assert len(line) == 1 and "MicroPython robot on" in line[0] and "touch(es)" in line[0]
    assert "failed tick" not in line[0]
