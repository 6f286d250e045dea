"""Perception as a run's measure (perception/tracker.py): the
`touchswarm run` summary fields and trace columns, consistent with each other
and with the evidence. Runs in-process; no timing."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from perception.evidence import iou
from perception.recognise import THRESHOLD
from perception.tracker import COLUMNS, Perceiver, attach
from sim_backend import objects, scenario
from sim_backend.engine import Engine
from tests.test_watch import run_cli

DOCS = Path(__file__).resolve().parents[1] / "docs" / "outputs.md"
FIELDS = ("estimate_iou", "estimate_kind", "hull_free_iou", "recognised", "p",
          "recognised_tick", "recognised_as", "recognition_threshold", "evidence")


def test_run_summary_and_trace_carry_the_estimate_and_recognition(tmp_path):
    trace = tmp_path / "t.csv"
    rc, out, err = run_cli("run", "--json", "--trace", str(trace))
    assert rc == 0, err
    s = json.loads(out)
    for k in FIELDS:
        assert k in s, k
    # the default scenario's bar is recognised, after the first touch and
    # before the end, with at least the threshold's confidence
    assert s["recognised"] == "bar" == s["recognised_as"]
    assert s["p"] >= s["recognition_threshold"] == THRESHOLD
    assert s["found_tick"] <= s["recognised_tick"] <= s["ticks"]
    assert s["estimate_kind"] == "map"
    # the new estimate beside the thesis's hull: never worse here
    assert 0.0 <= s["shape_iou"] <= s["estimate_iou"] <= 1.0
    ev = s["evidence"]
    assert ev["object"] == len(s["touches"]) and ev["conflicts"] == 0 and ev["free_seen"] > 0
    with trace.open() as f:
        rows = list(csv.DictReader(f))
    assert [c for c, _ in COLUMNS] == list(rows[0])[-len(COLUMNS):]
    assert float(rows[-1]["estimate_iou"]) == s["estimate_iou"]
    assert float(rows[-1]["p"]) == s["p"]
    assert rows[-1]["recognised"] == s["recognised"]
    first = next(r for r in rows if float(r["p"]) >= THRESHOLD)
    assert int(first["tick"]) == s["recognised_tick"]
    # before the first touch there is no estimate
    assert all(float(r["estimate_iou"]) == 0.0 for r in rows if int(r["touches"]) == 0)


def test_text_summary_names_the_recognised_shape():
    rc, out, err = run_cli("run", "--scenario", "X", "--seed", "3")
    assert rc in (0, 1), err
    assert "estimate IoU" in out and "recognised       " in out


def test_perceiver_follows_the_evidence_of_an_engine():
    sc = scenario.load("cross").replace(objectWeight=8.0, maxTicks=3000)
    e = Engine(sc, 5)
    p = attach(e)
    assert p is not None and p in e.instruments
    r = e.run()
    s = r.summary()
    assert len(p.curve) == r.ticks + 1            # tick 0 and every tick
    assert sorted(p.by_touches) == list(range(1, len(r.coordinator.touches) + 1))
    assert s["estimate_iou"] == iou(p.est, p.truth)
    # the evidence is kept in the object's frame: the touches are the true
    # object cells where it started, and no robot was ever seen on it
    assert p.ev.object_cells() <= p.truth
    assert not (p.ev.free_set() & p.truth)
    assert s["evidence"]["conflicts"] == 0


def test_without_free_evidence_only_touches_count():
    sc = scenario.load("default").replace(maxTicks=400)
    e = Engine(sc, 2)
    p = Perceiver(e, free_every=0)
    e.run()
    assert p.ev.free_cells == 0 and p.summary()["evidence"]["free_seen"] == 0
    assert p.ev.object_cells() == set(p.ev.touched)


def test_behaviours_without_an_object_get_no_perceiver():
    sc = scenario.load("default").replace(behaviour="aggregate", maxTicks=5)
    e = Engine(sc, 1)
    assert attach(e) is None and e.instruments == []
    assert "estimate_iou" not in e.run().summary()


def test_perception_columns_are_documented():
    text = DOCS.read_text()
    for name, _ in COLUMNS:
        assert f"`{name}`" in text, name


def test_bad_perceiver_parameters_are_refused():
    import pytest
    e = Engine(scenario.load("default").replace(maxTicks=5), 1)
    for kw, word in (({"threshold": 0.0}, "threshold"), ({"free_every": -1}, "free_every"),
                     ({"every": 0}, "every")):
        with pytest.raises(ValueError, match=word):
            Perceiver(e, **kw)
    assert e.instruments == [] and e.observers == []


def test_one_verdict_per_run_the_decision_is_the_summary():
    """With recognise = true the perception fields are the
    decision's own call (decoy seed 8 once said "target, p 0.978" beside
    `recognised_as: L, p 0.9996`)."""
    sc = scenario.load("decoy").replace(recognise=True, maxTicks=400)
    e = Engine(sc, 8)
    p = attach(e)
    s = e.run().summary()
    assert s["verdict_by"] == "decision" and p.decider is e.coordinator.decider
    assert s["target_tick"] is not None
    assert s["recognised"] == "bar" == s["recognised_as"]
    assert s["p"] == s["target_permille"] / 1000
    assert s["recognised_tick"] == s["target_tick"]
    assert s["recognition_threshold"] == sc.confidence
    assert s["estimate_iou"] == 1.0


def test_shape_iou_does_not_jump_during_the_transport():
    """Default seed 2 alternated 0.35 / 0.6875 every tick from
    119 to 156 (the hull against a moving object); in the object's own
    frame it only changes when a touch arrives."""
    from sim_backend.api import run
    r = run("default", 2)
    s = r.summary
    rows = r.ticks
    carry = rows[(rows["tick"] > s["converged_tick"]) & (rows["tick"] <= s["home_tick"])]
    assert len(carry) > 20
    assert carry["shape_iou"].nunique() == 1
    assert carry["shape_iou"].iloc[-1] == s["shape_iou"]


def test_a_sweep_row_carries_the_estimate_and_the_verdict(tmp_path):
    from sim_backend import sweep as sw
    pts = sw.grid_points({"objectWeight": [3.0]})
    rows = sw.sweep(pts, [1], base=scenario.load("default").replace(maxTicks=300),
                    engine="reference", until="converged")
    assert {"estimate_iou", "recognised", "p"} <= set(sw.columns(["thesis"]))
    row = rows[0]
    assert 0.0 < row["estimate_iou"] <= 1.0 and 0.0 < row["p"] <= 1.0
    assert row["recognised"] in (None, "unknown", *objects.SHAPES)
    path = sw.write_csv(rows, tmp_path / "sweep.csv", sw.columns(["thesis"]))
    back = sw.read_csv(path)[0]
    assert float(back["estimate_iou"]) == row["estimate_iou"]
