"""The whole mission on virtual CAN: the host process (HostProcess over a
CanTransport) in one thread, the simulated swarm behind one gateway bus in
another, on a private python-can virtual channel; with and without injected
faults (loss, duplicates, reordering) between robots and host.

Set TOUCHSWARM_CAN_BUS (e.g. socketcan://can0) to run the same tests on a real
bus: host and robots then open two handles on that interface."""

import os
import threading

import pytest

from bridge.host.journal import Journal
from bridge.host.process import HostProcess
from bridge.host.swarm import run_swarm, swarm_engine
from bridge.host.transport import CanTransport
from bridge.links import open_bus
from bridge.links.canlink import Faults, private_channel
from sim_backend import scenario

TICK = 0.002
REAL_BUS = os.environ.get("TOUCHSWARM_CAN_BUS")


def mission(sc, seed, faults=None, journal=None, stop_host_after=None, resume=None):
    url = REAL_BUS or f"virtual://{private_channel('hil')}"
    out = {}
    with open_bus(url) as rb:
        engine = swarm_engine(sc, seed, rb, *(faults or (None, None)))
        hosts = []
        # the host listens before the robots start (a virtual bus keeps no frames
        # for a bus that is not open yet)
        first = CanTransport(open_bus(url))

        def host_thread():
            if stop_host_after is not None:
                with first as tr:
                    h = HostProcess(tr, sc.weight_centi, sc.homeX, sc.homeY,
                                    journal=journal, tick_seconds=TICK)
                    hosts.append(h)
                    h.run(stop=lambda: len(h.coord.touches) >= stop_host_after,
                          max_ticks=20000)
                    # a crash loses everything in memory; the journal stays
            tr = first if stop_host_after is None else CanTransport(open_bus(url))
            with tr:
                h = HostProcess(tr, sc.weight_centi, sc.homeX, sc.homeY,
                                journal=journal, tick_seconds=TICK)
                if resume:
                    h.resume(journal)
                hosts.append(h)
                out["host"] = h.run(max_ticks=20000)

        th = threading.Thread(target=host_thread)
        th.start()
        try:
            out["robots"] = run_swarm(engine, TICK, stop=lambda: not th.is_alive())
        finally:
            th.join(60)
        out["hosts"] = hosts
    return out


def check_exactly_once(out, faults=False):
    h, r = out["host"], out["robots"]
    assert h["delivered"], h
    touches = [tuple(t) for t in h["touches"]]
    assert len(touches) == len(set(touches))
    assert set(touches) == {tuple(t) for t in r["reported"]}
    assert h["power"] == len(touches)           # rPower 1.0: one unit per touch
    # with loss, a report may overtake a robot's lost HELLOs: dropped, then retransmitted
    allowed = {"unannounced node"} if faults else set()
    assert set(h["bad_frames"]) <= allowed and r["bad_frames"] == {}


@pytest.mark.parametrize("seed", [1, 2])
def test_whole_mission_exactly_once(seed):
    out = mission(scenario.load("default"), seed)
    check_exactly_once(out)
    # The guarantee is exactly once, not "no retransmission": on a loaded
    # machine the 2 ms wall-clock ticks let a robot retransmit before its ACK
    # arrives (issue 8 §6); such duplicates are ACKed and never counted,
    # which check_exactly_once asserts.
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
        assert sorted((t.node, t.seq) for t in j.touches()) == sorted(
            tuple(t) for t in out["host"]["touches"])
