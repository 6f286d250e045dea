"""A tick's snapshot builds its fields on first read (sim_backend/observe.py):
one an observer keeps still holds its own tick's values after the run went
on; one nobody reads costs nothing. In process, reference engine, no timing."""

from __future__ import annotations

from sim_backend import observe, scenario
from sim_backend.engine import Engine

SC = scenario.load("default").replace(agents=6, maxTicks=40)


def test_a_kept_snapshot_holds_its_own_ticks_values():
    e = Engine(SC, 3, record_trajectories=True)
    kept: list[observe.Snapshot] = []
    e.observe(kept.append)
    e.run()
    assert [s.tick for s in kept] == list(range(1, 41))
    one = 256.0
    for s, (xs, ys), states in zip(kept, e.trajectories, e.states):
        assert s.xs == tuple(x / one for x in xs) and s.ys == tuple(y / one for y in ys)
        assert s.states == tuple(states)
    # the touches as they stood then: the list only grows in this run
    assert [len(s.touches) for s in kept] == sorted(len(s.touches) for s in kept)
    assert kept[-1].touches == observe.snapshot(e).touches


def test_fields_nobody_reads_are_not_built(monkeypatch):
    built: list[str] = []
    for name, build in list(observe._LAZY.items()):
        def counted(engine, name=name, build=build):
            built.append(name)
            return build(engine)
        monkeypatch.setitem(observe._LAZY, name, counted)
    e = Engine(SC, 3)
    seen: list[tuple[int, int]] = []
    e.observe(lambda s: seen.append((s.tick, s.msgs_up)))
    e.run()
    assert len(seen) == 40 and built == []
    e.observe(lambda s: s.iou)
    e.step()
    assert built == ["iou"]


def test_engine_snapshot_is_complete():
    e = Engine(SC, 3)
    s = e.snapshot()
    e.run()
    assert s.tick == 0 and len(s.xs) == 6 and s.touches == ()
