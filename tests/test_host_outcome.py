"""The host's word can be trusted: `delivered` means the
host's own model has the object home (a delivered tick); a mission the
coordinator stopped (stalled, no path home), one the robots abandoned, or one
stopped from outside is not delivered: a distinct `outcome`, exit status 1,
in the summary, the journal and the CLI output."""

from __future__ import annotations

import json

from bridge.cli import main
from bridge.host.journal import Journal
from bridge.host.process import HostProcess
from sim_backend.coordinator import HostCoordinator, members
from firmware_logic import messages as msg
from firmware_logic.roster import OUTCOMES
from sim_backend import scenario
from sim_backend.engine import Engine
from tests.test_journal import FakeTransport


class Ticks:
    """A clock that moves one host tick per read (no wall time)."""

    def __init__(self, step: float = 0.01) -> None:
        self.t = 0.0
        self.step = step

    def __call__(self) -> float:
        self.t += self.step
        return self.t


def stalled_journal(path) -> dict:
    """A mission whose transport never moves: the coordinator stops it as
    stalled (thesis STALL_TICKS) and halts the swarm; returns the summary."""
    tr = FakeTransport()
    with Journal(path) as j:
        h = HostProcess(tr, weight=100, journal=j)
        h.handle([(4, msg.HELLO, (1, 100, 1))])
        h.step()
        h.handle([(4, msg.TOUCH, (1, 2, 2, 3, 2, 100))])
        tr.inbox = []
        # the leader never reports a step done: the object does not move
        s = h.run(clock=Ticks(), max_ticks=5000)
        assert h.coord.stopped_tick >= 0 and h.coord.delivered_tick < 0
        assert j.outcome() == {"outcome": "stalled", "reason": s["reason"], "tick": s["ticks"]}
    return s


def test_a_stalled_mission_is_not_delivered(tmp_path) -> None:
    s = stalled_journal(tmp_path / "j.sqlite")
    assert s["outcome"] == "stalled" and s["delivered"] is False and s["home_tick"] is None
    assert "stalled" in s["reason"]


def test_the_cli_says_stalled_and_exits_1_for_a_resumed_stalled_mission(tmp_path, capsys) -> None:
    """`touchswarm host --resume` of a mission the coordinator stopped: it
    repeats the HALT and ends; it once printed DELIVERED, exit 0."""
    jp = tmp_path / "j.sqlite"
    stalled_journal(jp)
    capsys.readouterr()
    from bridge.links import open_bus
    with open_bus(f"slcan-pty://{tmp_path / 'ada'}"):        # an adapter, no robots
        rc = main(["host", "--bus", f"slcan://{tmp_path / 'ada'}?settle_ms=0", "--resume",
                   str(jp), "--tick-ms", "1", "--max-ticks", "50"])
    out = capsys.readouterr().out
    assert rc == 1
    last = out.strip().splitlines()[-1]
    assert last.startswith("NOT delivered (stalled: stopped at tick") and "DELIVERED" not in out
    with Journal(jp) as j:
        assert j.outcome()["outcome"] == "stalled"


def test_a_stopped_host_says_stopped_and_a_delivered_one_delivered(tmp_path) -> None:
    h = HostProcess(FakeTransport(), weight=100)
    s = h.run(clock=Ticks(), max_ticks=3)
    assert (s["outcome"], s["delivered"]) == ("stopped", False)
    assert s["reason"].startswith("gave up after 3 ticks")
    h = HostProcess(FakeTransport(), weight=100)
    s = h.run(clock=Ticks(), stop=lambda: True)
    assert s["outcome"] == "stopped" and s["reason"].startswith("stopped by a signal")
    # silent robots: the host gives up (stalled)
    h = HostProcess(FakeTransport(), weight=100)
    s = h.run(clock=Ticks(), bus_timeout=0.05)
    assert s["outcome"] == "stalled" and s["gave_up_on"] == "bus" and not s["delivered"]
    # delivered: the leader reports each step done until the model has it home
    tr = FakeTransport()
    h = HostProcess(tr, weight=100, home_x=0, home_y=0)
    h.handle([(4, msg.HELLO, (1, 100, 1))])
    h.step()
    h.handle([(4, msg.TOUCH, (1, 6, 5, 7, 5, 100))])
    for _ in range(200):
        h.step()
        c = h.coord
        if c.done():
            break
        x, y = c.leader_x + c.dx, c.leader_y + c.dy
        h.handle([(4, msg.HEARTBEAT, (4, x * 256, y * 256, 0, c.step))])
    s = h.run(clock=Ticks(), max_ticks=20)
    assert (s["outcome"], s["delivered"]) == ("delivered", True) and s["home_tick"] is not None
    assert set(OUTCOMES) == {"delivered", "halted", "stalled", "stopped"}
    assert "done" in members(HostCoordinator)


def test_an_in_process_run_names_its_outcome_for_any_behaviour() -> None:
    sc = scenario.load("default").replace(behaviour="aggregate", agents=6, maxTicks=5)
    s = Engine(sc, 1).run().summary()
    assert s["outcome"] == "stopped" and s["delivered"] is False
    sc = scenario.load("default").replace(agents=6, maxTicks=5)
    s = Engine(sc, 1).run().summary()
    assert s["outcome"] == "collecting touches" and s["delivered"] is False


def test_the_exit_status_follows_the_outcome_alone(tmp_path, capsys) -> None:
    """0 delivered, 1 every other outcome: silent robots (stalled, the host
    gave up) exit 1 like a stuck object, a halt or a stop (it was 3, alone
    among them). The CLI: no robot behind the adapter, a short bus limit."""
    from bridge.commands.host import exit_status
    assert [exit_status(o) for o in OUTCOMES] == [0, 1, 1, 1]
    from bridge.links import open_bus
    with open_bus(f"slcan-pty://{tmp_path / 'ada'}"):        # an adapter, no robots
        rc = main(["host", "--bus", f"slcan://{tmp_path / 'ada'}?settle_ms=0", "--json",
                   "--tick-ms", "1", "--bus-timeout", "0.02"])
    out = capsys.readouterr()
    s = json.loads(out.out.strip().splitlines()[-1])
    assert rc == 1 and s["outcome"] == "stalled" and s["gave_up_on"] == "bus"
    assert "host gave up at tick" in out.err and "(--bus-timeout)" in out.err
