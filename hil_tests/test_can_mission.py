"""The whole mission on virtual CAN: the host process (HostProcess.run over a
CanTransport) and the simulated swarm behind one gateway bus, on a private
python-can virtual channel; with and without injected faults (loss,
duplicates, reordering) between robots and host.

Both run on one SIMULATED clock, so the tests assert guarantees, not timing:
the swarm ticks inside the host's poll (`Lockstep`) whenever the host would
wait past a robot tick. With wall-clock ticks in two threads a loaded machine
decides who runs when (retransmissions that cross their ACK, a robot that
grasps after the host's last HALT), and the outcome was timing, not protocol.

Set TOUCHSWARM_CAN_BUS (e.g. socketcan://can0) to run the same tests on a real
bus: host and robots then open two handles on that interface."""

import os

import pytest

from bridge.host.journal import Journal
from bridge.host.process import HostProcess
from bridge.host.swarm import swarm_engine
from bridge.host.transport import CanTransport
from bridge.links import open_bus
from bridge.links.canlink import Faults, private_channel
from firmware_logic import messages as msg
from sim_backend import scenario

TICK = 0.01
REAL_BUS = os.environ.get("TOUCHSWARM_CAN_BUS")


class SimClock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


class Lockstep:
    """The host's transport, with the swarm ticking on the host's simulated
    clock: poll hands over the frames waiting; when there are none it moves the
    clock to the next robot tick (half a tick after the host's) and ticks the
    swarm, or to the poll's deadline."""

    def __init__(self, inner: CanTransport, engine, clock: SimClock) -> None:
        self.inner = inner
        self.engine = engine
        self.clock = clock
        self.next_robot_tick = clock.t + TICK / 2

    def poll(self, timeout):
        got = self.inner.poll(0.0)
        if got:
            return got
        deadline = self.clock.t + timeout
        if self.next_robot_tick <= deadline and not self.engine.finished():
            self.clock.t = max(self.clock.t, self.next_robot_tick)
            self.engine.step()
            self.next_robot_tick += TICK
            return self.inner.poll(0.0)
        self.clock.t = deadline
        return []

    def send(self, node, kind, fields):
        self.inner.send(node, kind, fields)

    def bad_frames(self):
        return self.inner.bad_frames()

    def close(self):
        self.inner.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def mission(sc, seed, faults=None, journal=None, stop_host_after=None, resume=None):
    from bridge.host.swarm import swarm_summary
    url = REAL_BUS or f"virtual://{private_channel('hil')}"
    out = {}
    clock = SimClock()
    with open_bus(url) as rb:
        engine = swarm_engine(sc, seed, rb, *(faults or (None, None)))
        hosts = []

        def host(resumed: bool) -> HostProcess:
            h = HostProcess(Lockstep(CanTransport(open_bus(url)), engine, clock),
                            sc.weight_centi, sc.homeX, sc.homeY, journal=journal,
                            tick_seconds=TICK)
            if resumed:
                h.resume(journal)
            hosts.append(h)
            return h

        if stop_host_after is not None:
            h = host(False)
            with h.transport:
                h.run(stop=lambda: len(h.coord.touches) >= stop_host_after,
                      max_ticks=20000, clock=clock)
            # a crash loses everything in memory (and the frames on its bus); the journal stays
        h = host(bool(resume))
        with h.transport:
            out["host"] = h.run(max_ticks=20000, clock=clock)
        out["robots"] = swarm_summary(engine)
        out["hosts"] = hosts
    return out


def check_exactly_once(out, faults=False, journal=None):
    """The guarantee: every touch counted once (a retransmission that crossed
    its ACK is a duplicate, re-ACKed and not counted), none lost, journalled
    once, and the object delivered. With faults, a report may still be waiting
    for its ACK when the mission ends (its frames kept being dropped): it is
    then not counted, and its robot knows it was not."""
    h, r = out["host"], out["robots"]
    assert h["delivered"], h
    touches = [tuple(t) for t in h["touches"]]
    assert len(touches) == len(set(touches))
    reported = {tuple(t) for t in r["reported"]}
    waiting = {t for t in reported if t[0] in r["unacked"]}
    assert reported - waiting <= set(touches) <= reported
    if not faults:
        assert r["unacked"] == []                   # every robot's report was ACKed
    assert h["power"] == len(touches)           # rPower 1.0: one unit per touch
    if journal is not None:
        assert sorted((r.node, r.fields[0]) for r in journal.reports(msg.TOUCH)) == sorted(touches)
    # with loss, a report may overtake a robot's lost HELLOs: dropped, then retransmitted
    allowed = {"unannounced node"} if faults else set()
    assert set(h["bad_frames"]) <= allowed and r["bad_frames"] == {}


@pytest.mark.parametrize("seed", [1, 2])
def test_whole_mission_exactly_once(seed, tmp_path):
    with Journal(tmp_path / "j.sqlite") as j:
        out = mission(scenario.load("default"), seed, journal=j)
        check_exactly_once(out, journal=j)
    assert out["robots"]["halted"]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_mission_with_loss_duplicates_and_reordering(seed):
    faults = (Faults(seed, loss=0.2, dup=0.1, window=4),
              Faults(seed + 100, loss=0.2, dup=0.1, window=4))
    out = mission(scenario.load("default"), seed, faults)
    check_exactly_once(out, faults=True)
    up, down = out["robots"]["faults_up"], out["robots"]["faults_down"]
    assert up["dropped"] > 0 and up["duplicated"] > 0 and down["dropped"] > 0


def test_host_restart_mid_run_loses_no_touch(tmp_path):
    sc = scenario.load("default").replace(objectWeight=6.0)
    with Journal(tmp_path / "j.sqlite") as j:
        out = mission(sc, 2, journal=j, stop_host_after=2, resume=True)
        check_exactly_once(out)
        first, second = out["hosts"]
        assert len(first.coord.touches) >= 2 and second.resumed >= 2
        assert sorted((r.node, r.fields[0]) for r in j.reports(msg.TOUCH)) == sorted(
            tuple(t) for t in out["host"]["touches"])


KILL_EVERY = 9        # host ticks between two deaths of the host


def test_host_killed_at_20_plus_points_resumes_to_delivery_exactly_once(tmp_path):
    """The host dies every KILL_EVERY ticks over a whole mission (before the
    first touch, between touches, during transport) and once more after
    delivery; a death loses everything in memory and the frames on its bus,
    the journal stays. Each successor resumes from the journal. The mission
    ends delivered, every touch counted exactly once, no transport step
    executed twice, and the host that resumes after delivery only repeats
    the HALT."""
    from bridge.host.swarm import swarm_summary
    sc = scenario.load("default").replace(objectWeight=6.0)
    url = REAL_BUS or f"virtual://{private_channel('hil')}"
    clock = SimClock()
    deaths: list[str] = []
    executed: dict[int, list[int]] = {}     # node -> transport steps it executed
    with Journal(tmp_path / "j.sqlite") as j, open_bus(url) as rb:
        engine = swarm_engine(sc, 2, rb)

        def host() -> HostProcess:
            h = HostProcess(Lockstep(CanTransport(open_bus(url)), engine, clock),
                            sc.weight_centi, sc.homeX, sc.homeY, journal=j, tick_seconds=TICK)
            if deaths:
                h.resume(j)
            return h

        orig_step = engine.step

        def step_and_watch() -> None:
            orig_step()
            for r in engine.robots:
                if r.done_step and executed.setdefault(r.node, [0])[-1] != r.done_step:
                    executed[r.node].append(r.done_step)
        engine.step = step_and_watch
        while True:
            h = host()
            start = h.tick
            span = 2 if not deaths else KILL_EVERY       # the first death: before any touch
            with h.transport:
                out = h.run(stop=lambda: h.tick >= start + span, max_ticks=20000,
                            clock=clock)
            if out["delivered"]:
                break
            c = h.coord
            deaths.append("transport" if c.converged_tick >= 0 else
                          "between touches" if c.touches else "before the first touch")
            assert len(deaths) < 400, "the mission makes no progress across deaths"
        deaths.append("after delivery")
        last = host()
        with last.transport:
            after = last.run(max_ticks=50, clock=clock)
        robots = swarm_summary(engine)
        journalled = sorted((r.node, r.fields[0]) for r in j.reports(msg.TOUCH))
    assert len(deaths) >= 20, deaths
    assert {"before the first touch", "between touches", "transport"} <= set(deaths), deaths
    touches = [tuple(t) for t in out["touches"]]
    assert len(touches) == len(set(touches))                        # none counted twice
    assert set(touches) == {tuple(t) for t in robots["reported"]}   # none lost
    assert journalled == sorted(touches)
    assert out["power"] == len(touches) * 1.0
    for node, steps in executed.items():                            # no step run twice
        assert len(steps) == len(set(steps)), (node, steps)
    # the host resumed after delivery knows it: delivered, no new transport step
    assert after["delivered"] and after["transport_step"] == out["transport_step"]
    assert robots["halted"]
