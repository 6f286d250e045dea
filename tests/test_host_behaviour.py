"""`touchswarm host --behaviour NAME` builds its coordinator through the
registry and serves any behaviour whose coordinator meets the host contract
(firmware_logic/roster.py, bridge/host/process.py): the thesis and
aggregation both run in the host process with journal and resume; the
journal holds each behaviour's reports in the message table's layout; a
behaviour that lacks the contract is refused in one line."""

from __future__ import annotations

import shutil

import pytest

from bridge.cli import main
from bridge.host.journal import Journal
from bridge.host.process import HostProcess, host_behaviour
from bridge.host.swarm import swarm_engine, swarm_summary
from bridge.host.transport import CanTransport
from bridge.links import open_bus
from bridge.links.canlink import private_channel
from firmware_logic import messages as msg
from sim_backend import registry
from firmware_logic.behaviours.aggregate.spec import LEAVE
from hil_tests.test_can_mission import TICK, Lockstep, SimClock
from sim_backend import scenario
from tests.test_journal import FakeTransport

AGG = scenario.load("default").replace(behaviour="aggregate")


def test_host_runs_thesis_and_aggregate_through_the_registry() -> None:
    h = HostProcess(FakeTransport(), weight=500, behaviour="thesis")
    assert type(h.coord).__module__ == "firmware_logic.behaviours.thesis.coordinator"
    a = HostProcess(FakeTransport(), weight=500, behaviour="aggregate", scenario=AGG)
    assert type(a.coord).__module__ == "firmware_logic.behaviours.aggregate.coordinator"


def oldstyle(tmp_path, name, body):
    """A copy of aggregate whose make_coordinator is `body`."""
    folder = tmp_path / name
    shutil.copytree(registry.load("aggregate").folder, folder,
                    ignore=shutil.ignore_patterns("__pycache__"))
    init = folder / "__init__.py"
    text = init.read_text()
    init.write_text(text[:text.index("def make_coordinator(")] + body)
    return folder


def test_a_behaviour_without_the_host_contract_is_refused_in_one_line(tmp_path, capsys) -> None:
    """A behaviour folder whose make_coordinator takes no on_reject (what an
    old scaffold wrote), or whose coordinator is no Roster (cannot replay a
    journal, snapshot its state or say it is done), is refused before any
    port or journal is touched."""
    from bridge.errors import UsageError
    folder = oldstyle(tmp_path, "nokeywords", (
        "def make_coordinator(sc, journal=None, cells=None):\n"
        "    from firmware_logic.behaviours.aggregate.coordinator import Coordinator\n"
        "    return Coordinator(sc.agents, 80, journal=journal)\n"))
    with pytest.raises(UsageError, match="lacks on_reject"):
        host_behaviour(str(folder))
    assert main(["host", "--behaviour", str(folder), "--bus", "slcan:///nonexistent"]) == 2
    err = capsys.readouterr().err.strip()
    assert "cannot run in the host process" in err and "\n" not in err
    bare = oldstyle(tmp_path, "noroster", (
        "class Bare:\n"
        "    def __init__(self):\n"
        "        self.nodes, self.touches, self.rejected = {}, [], {}\n"
        "    def on_message(self, node, kind, f, tick):\n"
        "        pass\n"
        "    def tick(self, tick):\n"
        "        return []\n\n\n"
        "def make_coordinator(sc, journal=None, cells=None, on_reject=None):\n"
        "    return Bare()\n"))
    with pytest.raises(UsageError, match="lacks delivered_tick, status, replay, snapshot, "
                                         "adopt, decision, done, carriers, quiet"):
        host_behaviour(str(bare), AGG)
    assert main(["host", "--behaviour", str(bare), "--bus", "slcan:///nonexistent"]) == 2
    assert "derive it from firmware_logic.roster.Roster" in capsys.readouterr().err
    assert main(["host", "--behaviour", "nosuch", "--bus", "slcan:///nonexistent"]) == 2
    assert "not an installed behaviour" in capsys.readouterr().err


def test_a_journal_of_another_behaviour_is_refused(tmp_path, capsys) -> None:
    path = tmp_path / "j.sqlite"
    with Journal(path) as j:
        HostProcess(FakeTransport(), weight=500, journal=j, behaviour="aggregate", scenario=AGG)
        assert j.behaviour() == "aggregate"
    assert main(["host", "--resume", str(path), "--bus", "slcan:///dev/null"]) == 2
    err = capsys.readouterr().err.strip()
    assert "written by a host of behaviour 'aggregate', not 'thesis'" in err and "\n" not in err


def test_the_host_limits_aggregate_acks_and_rejects_changed_hellos() -> None:
    """What Roster gives every behaviour: one ACK per node per tick, a HELLO
    that changes a node refused, reports from unannounced nodes refused."""
    t = FakeTransport()
    h = HostProcess(t, weight=500, behaviour="aggregate", scenario=AGG)
    t.inbox = [(3, msg.HELLO, (1, 100, 1))] * 1000 + [(3, msg.HELLO, (2, 100, 1)),
                                                      (4, msg.TOUCH, (1, 0, 0, 1, 0, 100))]
    h.handle(t.poll(0))
    h.step()
    assert [m for m in t.sent if m[1] == msg.ACK] == [(3, msg.ACK, (0,))]
    assert h.coord.nodes == {3: (1, 100)}
    assert h.coord.rejected == {"hello changes model or power": 1}
    assert h.bad_frames() == {"unannounced node": 1}


def aggregate_mission(url, engine, clock, journal, stop_after=None, resumed=False,
                      max_ticks=20000):
    sc = engine.sc
    h = HostProcess(Lockstep(CanTransport(open_bus(url)), engine, clock), sc.weight_centi,
                    sc.homeX, sc.homeY, journal=journal, tick_seconds=TICK,
                    behaviour="aggregate", scenario=sc)
    if resumed:
        h.resume(journal)
    stop = None if stop_after is None else (lambda: len(h.coord.touches) >= stop_after)
    with h.transport:
        out = h.run(stop=stop, max_ticks=max_ticks, clock=clock)
    return h, out


def stops(c):
    return sorted((s.node, s.seq) for s in c.touches)


def replayed(journal, sc):
    """A fresh host's coordinator after replaying the journal."""
    h = HostProcess(FakeTransport(), sc.weight_centi, behaviour="aggregate", scenario=sc)
    h.resume(journal)
    return h.coord


def check_stops(h, out, engine, journal):
    """The quorum reached and the swarm halted; every robot counted at most
    once; replaying the journal gives exactly the coordinator's stops."""
    c = h.coord
    nodes = [s.node for s in c.touches]
    assert out["delivered"] and c.power == len(nodes) >= c.need
    assert len(nodes) == len(set(nodes))
    assert swarm_summary(engine)["halted"]
    again = replayed(journal, engine.sc)
    assert stops(again) == stops(c) and again.done()


def test_aggregate_runs_in_the_host_process_with_its_journal(tmp_path) -> None:
    sc = scenario.load("default").replace(behaviour="aggregate", quorum=50)
    url = f"virtual://{private_channel('agg')}"
    with Journal(tmp_path / "j.sqlite") as j, open_bus(url) as rb:
        engine = swarm_engine(sc, 3, rb)
        h, out = aggregate_mission(url, engine, SimClock(), j)
        check_stops(h, out, engine, j)
        assert j.behaviour() == "aggregate"


def test_aggregate_host_killed_and_resumed_counts_every_stop_once(tmp_path) -> None:
    """The host dies after 12 stops (everything in memory and on its bus lost,
    the journal kept); a new host resumes from the journal and the mission
    ends at the quorum with each stop counted once, the released ones not
    restored."""
    sc = scenario.load("default").replace(behaviour="aggregate", quorum=90)
    url = f"virtual://{private_channel('agg')}"
    clock = SimClock()
    with Journal(tmp_path / "j.sqlite") as j, open_bus(url) as rb:
        engine = swarm_engine(sc, 4, rb)
        first, out = aggregate_mission(url, engine, clock, j, stop_after=12)
        assert not out["delivered"]
        held = stops(first.coord)
        assert len(held) >= 12 and stops(replayed(j, sc)) == held
        second, out = aggregate_mission(url, engine, clock, j, resumed=True)
        assert second.resumed == len(held)
        check_stops(second, out, engine, j)
        # robots left their stops on the way: their LEAVEs (or HEARTBEATs out
        # of STAY) are journalled and replayed, so those stops are not restored
        left = len(j.reports(LEAVE)) + len(j.reports(msg.HEARTBEAT))
        assert left > 0 and len(j.reports(msg.TOUCH)) > len(second.coord.touches)
