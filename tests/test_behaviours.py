"""The behaviour seam: registry, a second behaviour end to end, the scaffold."""

from __future__ import annotations

import shutil
import sys
from pathlib import Path

import pytest

from bridge.cli import main
from bridge.firmware.conformance import RunParams, run_conformance
from sim_backend import registry
from sim_backend.engine import Engine
from sim_backend.scenario import load


def mission(b: registry.Behaviour, seed: int, **changes):
    # the seam: the scenario names the behaviour; the engine asks the registry
    ref = b.name if b.name in registry.names() else str(b.folder)
    e = Engine(load().replace(behaviour=ref, **changes), seed)
    assert type(e.robots[0]) is b.robot_class
    return e, e.run()


def test_registry_lists_both_and_refuses_unknown(capsys: pytest.CaptureFixture[str]) -> None:
    assert {"thesis", "aggregate"} <= set(registry.names())
    assert main(["behaviours"]) == 0
    out = capsys.readouterr().out
    assert "thesis" in out and "aggregate" in out and "search, climb, stay, halt" in out
    with pytest.raises(registry.BehaviourError, match="not an installed behaviour"):
        registry.load("no-such-behaviour")


def test_folder_without_spec_is_refused(tmp_path: Path) -> None:
    (tmp_path / "half").mkdir()
    (tmp_path / "half" / "__init__.py").write_text("ROBOT = 'robot:Robot'\n")
    with pytest.raises(registry.BehaviourError, match="no spec.py"):
        registry.load(tmp_path / "half")


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_aggregation_reaches_quorum_and_halts(seed: int) -> None:
    b = registry.load("aggregate")
    e, r = mission(b, seed, maxTicks=3000)
    c = e.coordinator
    assert c.delivered_tick > 0, "the quorum never stopped"
    stay = b.spec.STATES.index("stay")
    staying = {rb.node for rb in e.robots if rb.state == stay}
    # the host's count is the truth on the ground: every robot it counts has stopped
    assert set(c.stopped) <= staying | {rb.node for rb in e.robots
                                        if rb.state == b.spec.STATES.index("halt")}
    assert len(c.stopped) >= c.need
    m = c.measures()
    assert m["stopped"] == len(c.stopped) and 1 <= m["clusters"] <= m["stopped"]
    assert m["largest"] >= 2      # a stop needs a touch: nobody stops alone


def test_scaffold_runs_like_its_template(tmp_path: Path,
                                         capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["behaviour", "new", "chain", "--into", str(tmp_path)]) == 0
    chain = registry.load(tmp_path / "chain")
    assert chain.name == "chain"
    assert chain.robot_class.__module__ == registry.folder_module_name((tmp_path / "chain").resolve()) + ".robot"
    _, a = mission(registry.load("aggregate"), 4, maxTicks=500)
    _, c = mission(chain, 4, maxTicks=500)
    assert c.summary()["found_tick"] == a.summary()["found_tick"]
    assert list(c.world.xs) == list(a.world.xs)
    assert main(["behaviour", "new", "Bad-Name"]) == 2
    assert "lower-case Python identifier" in capsys.readouterr().err


def test_a_folder_does_not_shadow_an_installed_behaviour_of_its_name(tmp_path: Path) -> None:
    """A copy of aggregate in a folder named "aggregate", loaded in the same
    process as the installed one: each keeps its own modules."""
    installed = registry.load("aggregate")
    folder = tmp_path / "aggregate"
    shutil.copytree(installed.folder, folder, ignore=shutil.ignore_patterns("__pycache__"))
    (folder / "spec.py").write_text((folder / "spec.py").read_text()
                                    .replace('TITLE = ', 'TITLE = "copy " + '))
    copy = registry.load(folder)
    assert copy.module_name != installed.module_name
    assert copy.ref == str(folder.resolve()) and installed.ref == "aggregate"
    assert copy.spec.TITLE == "copy " + installed.spec.TITLE
    assert registry.load("aggregate").spec is installed.spec
    assert "aggregate" not in sys.modules       # nor under its bare folder name


def test_aggregation_on_micropython_matches_cpython_with_zero_heap() -> None:
    rep = run_conformance(params=RunParams(behaviour="aggregate", ticks=1500), heap_steps=1500)
    assert rep.errors == []
    assert rep.states == ["search", "climb", "stay", "halt"]
    for m in rep.models:
        assert m.identical, m.divergence
        assert m.heap_bytes == 0 and m.heap_locked_ok
        assert set(m.states_visited) == set(rep.states)


def test_a_behaviours_own_message_travels_and_counts() -> None:
    """aggregate's LEAVE (declared in its spec.py, kind 7): a robot that walks
    away from its stop sends it, the CAN codec carries it like a link message,
    and the coordinator drops that stop (and only that one) at once."""
    from bridge.links import codec
    from firmware_logic import messages as msg
    agg = registry.load("aggregate").activate()
    leave = agg.spec.LEAVE
    assert msg.fields(leave) == (("seq", 1, 0), ("x", 2, 1), ("y", 2, 1))
    frame = codec.encode(4, leave, (3, 512, -256))
    assert codec.Decoder("host").decode(frame) == (4, leave, (3, 512, -256))
    assert codec.Decoder("robot").decode(frame) is None      # a report, not a command
    c = agg.coordinator(load("default").replace(behaviour="aggregate"))
    c.on_message(4, msg.HELLO, (1, 100, 1), 1)
    c.on_message(4, msg.TOUCH, (3, 0, 0, 1, 0, 100), 2)
    c.on_message(4, leave, (2, 0, 0), 3)                     # a stale seq: ignored
    assert [t.node for t in c.touches] == [4]
    c.on_message(4, leave, (3, 0, 0), 4)
    assert c.touches == []


def test_robots_leave_over_a_long_aggregation() -> None:
    """In a mission with a quorum it cannot reach soon, robots do leave their
    stops and the host's count follows their LEAVE messages."""
    sc = load("default").replace(behaviour="aggregate", quorum=100, maxTicks=600)
    e = Engine(sc, 2)
    leaves = []
    orig = e.coordinator.on_message

    def spy(node, kind, f, tick):
        if kind == e.behaviour.spec.LEAVE:
            leaves.append(node)
        orig(node, kind, f, tick)
    e.coordinator.on_message = spy
    r = e.run()
    assert leaves, "no robot left its stop in 600 ticks: the test proves nothing"
    stay = e.behaviour.spec.STAY
    assert {t.node for t in r.coordinator.touches} == \
        {rb.node for rb in r.robots if rb.state == stay}


def test_run_of_another_behaviour_writes_records_and_picture(tmp_path: Path) -> None:
    assert main(["run", "--set", "behaviour=aggregate", "--out", str(tmp_path)]) == 0
    assert (tmp_path / "world.png").stat().st_size > 1000


def test_the_swarm_on_a_bus_knows_each_behaviours_states() -> None:
    """`touchswarm robots` (bridge/host/swarm.py) names states and waits for
    "halt" through the behaviour, not the thesis's constants."""
    from bridge.host.swarm import swarm_engine, swarm_summary
    from bridge.links import open_bus
    sc = load("default").replace(behaviour="aggregate", agents=6)
    with open_bus("virtual://behaviour-states-test") as bus:
        e = swarm_engine(sc, 1, bus)
        e.step()
        s = swarm_summary(e)
        assert set(s["states"]) <= {"search", "climb", "stay", "halt"} and not s["halted"]
        assert not e.finished()
        for r in e.robots:
            r.state = e.behaviour.halt_state
        assert e.finished() and swarm_summary(e)["halted"]
        assert e.behaviour.state_name(e.behaviour.halt_state) == "halt"


def test_installed_behaviours_are_read_once_per_process(monkeypatch):
    """Every scenario and world loads its behaviour; the installed packages'
    entry points are read once, not on each load (13 ms a read here)."""
    import importlib.metadata
    real = importlib.metadata.entry_points
    calls = []

    def counting(**kw):
        calls.append(kw)
        return real(**kw)
    registry._entry_points.cache_clear()
    monkeypatch.setattr(importlib.metadata, "entry_points", counting)
    try:
        for _ in range(5):
            assert registry.load("thesis").name == "thesis"
            assert "aggregate" in registry.names()
    finally:
        registry._entry_points.cache_clear()
    assert calls == [{"group": registry.GROUP}]
