"""Open-set recognition: a shape not in the library is called
"unknown" with its own outline, not the nearest template; a shape a
scenario adds ([[library]]) is recognised like a built-in; the seeded
polyomino set the bench measures (bench/open_set.py) is what it says.
The quality figures over all 24 shapes are the bench's (docs/perception.md);
these tests run the path on a few shapes, in-process and small."""

from __future__ import annotations

import pytest

from perception.evidence import Evidence, iou
from perception.recognise import THRESHOLD, UNKNOWN, estimate, recognise
from perception.shapes import Library, orientations
from perception.tracker import Perceiver
from sim_backend import objects
from sim_backend.api import scenario_of
from sim_backend.engine import Engine
from sim_backend.errors import ScenarioError
from tests.polyominoes import SEED, SIZES, art, polyominoes, reachable
from tests.test_perception_recognise import full_evidence

LIB = Library.builtin()
SHAPES = polyominoes(24, SEED)


def connected(cells) -> bool:
    cs = set(cells)
    todo, seen = [next(iter(cs))], set()
    while todo:
        x, y = todo.pop()
        if (x, y) in seen:
            continue
        seen.add((x, y))
        todo += [c for c in ((x + 1, y), (x - 1, y), (x, y + 1), (x, y - 1)) if c in cs]
    return seen == cs


def test_the_polyomino_set_is_seeded_distinct_connected_and_not_built_in():
    assert polyominoes(24, SEED) == SHAPES            # the same set every time
    assert polyominoes(24, SEED + 1) != SHAPES
    assert len(SHAPES) >= 20
    assert all(SIZES[0] <= len(s) <= SIZES[1] for s in SHAPES)
    assert len({len(s) for s in SHAPES}) >= 8         # sizes spread over 4..20
    assert all(connected(s) for s in SHAPES)
    builtin = {o for n in objects.SHAPES for o in orientations(objects.offsets(n))}
    images = [set(orientations(s)) for s in SHAPES]
    assert not any(im & builtin for im in images)
    assert all(not (a & b) for i, a in enumerate(images) for b in images[i + 1:])
    assert art(((0, 0), (1, 0), (1, 1))) == ".#\n##"
    assert reachable(((0, 0), (1, 0), (2, 0))) == 3
    with pytest.raises(ValueError, match="polyominoes"):
        polyominoes(0)


@pytest.mark.parametrize("j", [0, 7, 12])
def test_a_shape_outside_the_library_is_unknown_with_its_own_outline(j):
    placed = {(x - 3, y - 2) for x, y in SHAPES[j]}
    ev = full_evidence(placed)
    rec = recognise(ev, LIB)
    assert rec.best == UNKNOWN and rec.p >= THRESHOLD, rec.posterior
    assert rec.unknown and rec.map_pose is None
    assert iou(estimate(ev, rec), placed) >= 0.8
    # the closed library (the old behaviour) names the nearest template instead
    assert recognise(ev, LIB, p_open=0.0).best != UNKNOWN
    # added to the library, the same evidence names it
    known = recognise(ev, Library.builtin({"mine": SHAPES[j]}))
    assert known.best == "mine" and known.recognised() and known.map_cells == placed


@pytest.mark.parametrize("name", list(objects.SHAPES))
def test_the_built_ins_stay_recognised_with_the_open_set(name):
    placed = set(objects.cells(name, -4, -4))
    rec = recognise(full_evidence(placed), LIB)
    assert rec.best == name and rec.recognised(), rec.posterior
    assert rec.posterior[UNKNOWN] < 0.05


def test_joined_links_the_touches_around_free_cells():
    ev = Evidence(9)
    ev.touch(0, 0)
    ev.touch(2, 0)
    ev.free(1, 0)
    shape = ev.joined()
    assert {(0, 0), (2, 0)} <= shape and (1, 0) not in shape
    assert len(shape) == 5                        # round the free cell: two more steps


def test_library_key_adds_a_shape_and_bad_tables_are_refused():
    cells = [list(c) for c in SHAPES[3]]
    sc = scenario_of({"library": [{"name": "crate", "cells": cells},
                                  {"name": "hook", "art": "##\n#."}]})
    assert [p.name for p in sc.library] == ["crate", "hook"]
    assert scenario_of(sc.to_dict()).library == sc.library     # round trip
    lib = Library.of(sc)
    assert {"crate", "hook"} <= set(lib.names) and "bar" in lib.names
    for bad, msg in [([{"cells": cells}], r"library\[0\]\.name: required"),
                     ([{"name": "a", "cells": cells, "at": [1, 1]}], "unknown key 'at'"),
                     ([{"name": "a", "cells": cells}, {"name": "a", "shape": "L"}],
                      r"library\[1\]\.name: 'a' is taken"),
                     ([{"name": "unknown", "cells": cells}], "reserved"),
                     ([{"name": "a"}], "give exactly one of art, cells or shape")]:
        with pytest.raises(ScenarioError, match=msg):
            scenario_of({"library": bad})
    with pytest.raises(ScenarioError, match=r"objects\[0\]\.name: 'unknown' is reserved"):
        scenario_of({"objects": [{"name": "unknown", "shape": "L"}]})


def test_a_run_on_a_drawn_shape_reports_it_unknown_and_a_library_entry_names_it():
    """The whole path in a run: the default engine's Perceiver on a drawn
    6-cell polyomino (weight 5: converges by tick 73)."""
    cells = [list(c) for c in SHAPES[17]]
    base = {"agents": 20, "maxTicks": 600,
            "objects": [{"name": "thing", "cells": cells, "weight": 5.0}]}
    out = {}
    for key, extra in (("open", {}), ("added", {"library": [{"name": "thing6", "cells": cells}]})):
        e = Engine(scenario_of({**base, **extra}), 1)
        p = Perceiver(e)
        while e.coordinator.converged_tick < 0 and e.tick < 600:
            e.step()
        out[key] = p.summary()
    assert out["open"]["recognised"] == UNKNOWN and out["open"]["estimate_iou"] >= 0.8
    assert out["added"]["recognised"] == "thing6" and out["added"]["estimate_iou"] == 1.0


def test_the_bench_measures_one_run_and_tables_it():
    """bench/open_set.py (docs/perception.md's tables) on one small shape:
    the run, its calls and the calibration table; the 24-shape figures are
    the bench's, not the suite's."""
    import importlib.util
    from pathlib import Path
    path = Path(__file__).resolve().parents[1] / "bench" / "open_set.py"
    spec = importlib.util.spec_from_file_location("open_set_bench", path)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    assert len(bench.jobs(1)) == bench.SHAPES + bench.ADDED + len(objects.SHAPES)
    row = bench.one(("drawn", "poly17", SHAPES[17], 1, UNKNOWN))
    assert row["converged"] and row["best"] == UNKNOWN and row["estimate_iou"] >= 0.8
    assert len(row["calls"]) == row["touches"]
    out = bench.summarise([row])
    assert out["drawn"]["right_at_convergence"] == 1 and out["drawn"]["wrong_library_sure"] == 0
    assert sum(b["calls"] for b in out["calibration"]) == row["touches"]


def test_the_crate_is_reported_unknown_with_its_outline():
    """docs/perception.md's example: `touchswarm run --scenario crate --seed 1`."""
    from tests.test_watch import run_cli
    import json
    rc, out, err = run_cli("run", "--scenario", "crate", "--seed", "1", "--json")
    s = json.loads(out)
    assert s["recognised"] == UNKNOWN and s["p"] >= 0.999
    assert s["estimate_iou"] == 1.0 and round(s["shape_iou"], 2) == 0.55
