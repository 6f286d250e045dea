"""Aggregation in two processes: `touchswarm robots --behaviour aggregate`
behind an SLCAN face on a pty and `touchswarm host --behaviour aggregate` on
it, the host SIGKILLed after its journal holds stops and restarted with
--resume; the swarm halts at the quorum with each stop counted once."""

import json
import os
import signal
import subprocess

from bridge.host.journal import Journal
from bridge.host.process import HostProcess
from firmware_logic import messages as msg
from hil_tests.test_can_host_restart import EXE, lines_of, stop_all, wait_for
from sim_backend import scenario
from tests.test_journal import FakeTransport

SC = ["--scenario", "default", "--behaviour", "aggregate", "--set", "quorum=80",
      "--seed", "4", "--set", "maxTicks=20000"]


def replayed(j: Journal) -> HostProcess:
    """A fresh host that replayed journal `j` (the live stops it resumes with)."""
    h = HostProcess(FakeTransport(), 0, behaviour="aggregate",
                    scenario=scenario.load("default").replace(behaviour="aggregate", quorum=80))
    h.resume(j)
    return h


def test_aggregate_host_sigkill_and_resume_over_slcan_pty(tmp_path):
    adapter = tmp_path / "adapter"
    journal = tmp_path / "host.sqlite"
    robots = subprocess.Popen([EXE, "robots", "--bus", f"slcan-pty://{adapter}", *SC,
                               "--tick-ms", "4", "--linger-ms", "1500", "--json"],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    procs = [robots]
    try:
        wait_for(lines_of(robots.stderr), lambda s: "robots on" in s[-1], 60)
        bus = f"slcan://{adapter}?settle_ms=0"
        host = subprocess.Popen([EXE, "host", "--bus", bus, *SC, "--journal", str(journal),
                                 "--tick-ms", "4", "--json"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        procs.append(host)
        # each "TOUCH from robot" line follows the stop's journal write
        wait_for(lines_of(host.stderr), lambda s: sum("TOUCH from robot" in x for x in s) >= 3, 120)
        os.kill(host.pid, signal.SIGKILL)
        host.wait(10)
        with Journal(journal) as j:       # what a resumed host must start from
            held = len(replayed(j).coord.touches)
        again = subprocess.Popen([EXE, "host", "--bus", bus, *SC, "--resume", str(journal),
                                  "--tick-ms", "4", "--json"],
                                 stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        procs.append(again)
        out, err = again.communicate(timeout=300)
        assert again.returncode == 0, err
        h = json.loads(out.strip().splitlines()[-1])
        rout, _ = robots.communicate(timeout=120)
        r = json.loads(rout.strip().splitlines()[-1])
    finally:
        stop_all(procs)
    assert f"resumed {held} touches" in err and h["resumed"] == held
    assert h["delivered"] and r["halted"]
    nodes = [t[0] for t in h["touches"]]
    assert len(nodes) == len(set(nodes)) and len(nodes) >= 16     # 80 % of 20, once each
    # each held stop is one its robot reported: that report or a later one is
    # the robot's last (a robot may leave and stop again after the quorum,
    # before the HALT reaches it; the quorum's stops stay the result)
    latest = dict(tuple(t) for t in r["reported"])
    assert all(node in latest and seq <= latest[node] for node, seq in h["touches"])
    with Journal(journal) as j:
        # every stop journalled exactly once across the kill (a retransmission
        # to the resumed host is a duplicate), and replaying the journal gives
        # the stops the host halted on
        stops = [(x.node, x.fields[0]) for x in j.reports(msg.TOUCH)]
        assert len(stops) == len(set(stops)) and j.behaviour() == "aggregate"
        fresh = replayed(j)
    assert sorted([s.node, s.seq] for s in fresh.coord.touches) == sorted(h["touches"])
