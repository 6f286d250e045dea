"""A batch's recognitions at once (perception/recognise.py recognise_all,
perception/tracker.py end_fields_all, as soa.run_batch takes a sweep
chunk's): the same verdicts, posteriors and placements, float for float, as
each run's alone, on real runs' evidence. In-process reference runs; no
timing."""

from __future__ import annotations

from perception.evidence import Evidence
from perception.recognise import recognise, recognise_all
from perception.shapes import Library
from perception.tracker import end_fields, end_fields_all
from sim_backend import scenario
from sim_backend.engine import Engine

# scenarios whose runs end with touches of different boxes and counts, and
# a drawn object's library (X: a shape of its own beside the built-ins)
RUNS = [("default", s) for s in (1, 2, 3, 4, 5, 6)] + [("X", s) for s in (1, 2, 3)]


def finished() -> list:
    return [Engine(scenario.load(name).replace(maxTicks=2000), seed).run() for name, seed in RUNS]


def fields(rec) -> tuple:
    return rec.posterior, rec.best, rec.p, rec.map_cells, rec.map_pose, rec.map_origin


def evidence_of(result) -> Evidence:
    """The end state as end_fields reads it: the touches only (no robot's
    cell), so that the batch mixes sparse and full evidence."""
    ev = Evidence(result.scenario.worldSize)
    for t in result.coordinator.touches:
        ev.touch(t.sx, t.sy)
    return ev


def test_end_fields_of_a_batch_are_each_runs_alone():
    results = finished()
    alone = [end_fields(r) for r in results]
    assert all(a["estimate_iou"] > 0.0 for a in alone), alone      # every run touched
    assert len({(a["recognised"], a["p"]) for a in alone}) > 3      # verdicts that differ
    assert end_fields_all(results) == alone
    assert end_fields_all(results[::-1]) == alone[::-1]


def test_recognise_all_matches_recognise_on_real_evidence():
    results = finished()
    lib = Library.builtin()
    evs = [evidence_of(r) for r in results] + [Evidence(18)]       # one with no touch
    for p_open in (0.5, 0.0):
        batch = recognise_all(evs, lib, p_open=p_open)
        alone = [recognise(ev, lib, p_open=p_open) for ev in evs]
        assert [fields(r) for r in batch] == [fields(r) for r in alone]
    assert batch[-1].best is None and batch[0].best is not None
