"""A run reports the world's measures only when its behaviour declares them
power, shape_iou, segments, leader... are thesis words, so
an aggregation run's summary.json, sweep.csv and trace have none of them,
while the thesis's have each one it declares in spec.MEASURES."""

from __future__ import annotations

import csv
from pathlib import Path

from sim_backend import registry
from sim_backend import engine, scenario, sweep, trace

THESIS_WORDS = {"power", "shape_iou", "polygon_iou", "segments", "leader", "converged_moves"}


def _run(behaviour: str) -> engine.RunResult:
    sc = scenario.validate({"behaviour": behaviour, "agents": 12, "maxTicks": 40})
    return engine.Engine(sc, seed=3).run()


def test_an_aggregation_summary_has_no_thesis_words() -> None:
    s = _run("aggregate").summary()
    assert not THESIS_WORDS & set(s), sorted(THESIS_WORDS & set(s))
    for name, _ in registry.load("aggregate").spec.MEASURES:
        assert name in s
    assert {"ticks", "touches", "delivered", "seed"} <= set(s)


def test_the_thesis_summary_has_every_measure_it_declares() -> None:
    s = _run("thesis").summary()
    declared = {name for name, _ in registry.load("thesis").spec.MEASURES}
    assert THESIS_WORDS <= declared
    # (the recognise measures come only with recognise = true)
    assert THESIS_WORDS | {"found_tick", "converged_tick", "home_tick"} <= set(s)


def test_sweep_csv_columns_follow_the_declared_measures(tmp_path: Path) -> None:
    agg = sweep.columns(["aggregate"])
    assert not THESIS_WORDS & set(agg)
    assert {"stopped", "clusters", "largest"} <= set(agg)
    assert THESIS_WORDS <= set(sweep.columns(["thesis"]))
    sc = scenario.validate({"behaviour": "aggregate", "agents": 12, "maxTicks": 40})
    pt = sweep.Point("p", ())
    row = sweep.make_row(pt, sc, 3, _run("aggregate").summary(), "ticks")
    path = sweep.write_csv([row], tmp_path / "sweep.csv", agg)
    header = next(csv.reader(path.open()))
    assert "power" not in header and "largest" in header


def test_the_trace_has_power_and_shape_iou_only_where_declared() -> None:
    agg = [n for n, _ in trace.columns(registry.load("aggregate"))]
    th = [n for n, _ in trace.columns(registry.load("thesis"))]
    assert "power" not in agg and "shape_iou" not in agg and "polygon_iou" not in agg
    assert "touches" in agg
    assert "power" in th and "shape_iou" in th and "polygon_iou" in th
    sc = scenario.validate({"behaviour": "aggregate", "agents": 12, "maxTicks": 30})
    e = engine.Engine(sc, seed=3)
    t = trace.Trace(e)
    r = e.run()
    assert all(len(row) == len(t.names) for row in t.rows) and len(t.rows) == r.ticks
