"""Open-set perception (docs/perception.md): shapes the library
does not hold, shapes a scenario adds to it, and the built-ins.

Three groups of runs (20 firefly robots, default scenario otherwise,
reference engine, free evidence every tick):

  drawn     the random polyominoes of tests/polyominoes.py (24 shapes of
            4-20 cells, seed 30, none a built-in), each drawn as the
            scenario's object; the library is the built-ins only, so the
            right call is "unknown" with the shape's own outline;
  added     the first ADDED of those shapes again, now named in the
            scenario's [[library]]: the right call is its name;
  builtin   the 7 built-in objects: the right call is the shape.

The weight makes the run converge with holders on 80% of the object's
reachable segments (at most 12; the built-ins 12, as bench/perception.py).
A run's verdict is taken at convergence (the run stops there); the
calibration table counts every call the host makes on the way, one per
touch (the posterior when the k-th touch arrived).

Prints JSON: per group the mean estimate IoU at convergence, the wrong
library calls with p >= 0.9, the calibration table (calls by posterior
bin: how many, how many right) and per-run rows.

    .venv/bin/python bench/open_set.py [--seeds 3] [--workers 2]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from perception.evidence import iou  # noqa: E402
from perception.recognise import UNKNOWN  # noqa: E402
from perception.tracker import Perceiver  # noqa: E402
from sim_backend import objects  # noqa: E402
from sim_backend.api import scenario_of  # noqa: E402
from sim_backend.engine import Engine  # noqa: E402
from tests.polyominoes import SEED, polyominoes, reachable  # noqa: E402

SHAPES = 24
ADDED = 8
MAX_TICKS = 5000
SHARE = 0.8          # holders at convergence: this share of the reachable segments
MAX_HOLDERS = 12
BINS = (0.0, 0.5, 0.7, 0.9, 0.95, 0.99, 1.0001)
SURE = 0.9


def holders(cells) -> int:
    return max(2, min(MAX_HOLDERS, round(SHARE * reachable(cells))))


def scenario_for(group: str, name: str, cells) -> object:
    if group == "builtin":
        return scenario_of("default", {"object": name, "objectWeight": float(MAX_HOLDERS),
                                       "maxTicks": MAX_TICKS})
    d = {"agents": 20, "maxTicks": MAX_TICKS,
         "objects": [{"name": name, "cells": [list(c) for c in cells],
                      "weight": float(holders(cells))}]}
    if group == "added":
        d["library"] = [{"name": name, "cells": [list(c) for c in cells]}]
    return scenario_of(d)


def one(job: tuple) -> dict:
    group, name, cells, seed, right = job
    sc = scenario_for(group, name, cells)
    e = Engine(sc, seed)
    p = Perceiver(e)
    while e.coordinator.converged_tick < 0 and e.tick < MAX_TICKS:
        e.step()
    s = p.summary()
    calls = [(a.best, round(a.p, 6)) for _, a in sorted(p.by_touches.items())]
    return {"group": group, "shape": name, "cells": len(cells), "seed": seed,
            "right": right, "converged": e.coordinator.converged_tick >= 0, "tick": e.tick,
            "touches": len(p.ev.touched), "estimate_iou": s["estimate_iou"],
            "hull_iou": iou(p.ev.hull_cells(), p.truth), "best": p.rec.best,
            "p": round(p.rec.p, 6), "calls": calls}


def jobs(seeds: int) -> list[tuple]:
    out = []
    shapes = polyominoes(SHAPES, SEED)
    for seed in range(1, seeds + 1):
        for j, cells in enumerate(shapes):
            out.append(("drawn", f"poly{j}", cells, seed, UNKNOWN))
        for j, cells in enumerate(shapes[:ADDED]):
            out.append(("added", f"poly{j}", cells, seed, f"poly{j}"))
        for name in objects.SHAPES:
            out.append(("builtin", name, tuple(objects.offsets(name)), seed, name))
    return out


def calibration(rows: list[dict]) -> list[dict]:
    """Every call (one per touch) binned by its posterior: how many, how many right."""
    table = []
    for lo, hi in zip(BINS, BINS[1:]):
        cs = [(best, p, r["right"]) for r in rows for best, p in r["calls"] if lo <= p < hi]
        table.append({"p": f"{lo:g}-{min(hi, 1.0):g}", "calls": len(cs),
                      "right": sum(1 for b, _, ok in cs if b == ok)})
    return table


def summarise(rows: list[dict]) -> dict:
    out: dict = {}
    for g in ("drawn", "added", "builtin"):
        rs = [r for r in rows if r["group"] == g]
        if not rs:
            continue
        sure = [r for r in rs if r["p"] >= SURE]
        out[g] = {
            "runs": len(rs), "converged": sum(r["converged"] for r in rs),
            "mean_estimate_iou": round(sum(r["estimate_iou"] for r in rs) / len(rs), 3),
            "min_estimate_iou": min(r["estimate_iou"] for r in rs),
            "mean_hull_iou": round(sum(r["hull_iou"] for r in rs) / len(rs), 3),
            "right_at_convergence": sum(r["best"] == r["right"] for r in rs),
            "sure_at_convergence": len(sure),
            "sure_right": sum(r["best"] == r["right"] for r in sure),
            "wrong_library_sure": sum(1 for r in rs for b, p in r["calls"]
                                      if p >= SURE and b != r["right"] and b != UNKNOWN),
        }
    sure_calls = [(b, r["right"]) for r in rows for b, p in r["calls"] if p >= SURE]
    out["calls_p_ge_0.9"] = {"calls": len(sure_calls),
                             "right": sum(b == ok for b, ok in sure_calls)}
    out["calibration"] = calibration(rows)
    return out


def per_shape(rows: list[dict]) -> list[dict]:
    """The drawn shapes, one entry each over the seeds."""
    out = []
    for name in dict.fromkeys(r["shape"] for r in rows if r["group"] == "drawn"):
        rs = [r for r in rows if r["group"] == "drawn" and r["shape"] == name]
        out.append({"shape": name, "cells": rs[0]["cells"], "holders": rs[0]["touches"],
                    "estimate_iou": round(sum(r["estimate_iou"] for r in rs) / len(rs), 3),
                    "hull_iou": round(sum(r["hull_iou"] for r in rs) / len(rs), 3),
                    "verdicts": " ".join(f"{r['best']} {r['p']:.3f}" for r in rs)})
    return out


def markdown(out: dict, shapes: list[dict]) -> str:
    """docs/perception.md's two tables."""
    lines = ["| shape | cells | holders (seed 1) | estimate IoU | hull IoU | verdict, p (per seed) |",
             "|---|---|---|---|---|---|"]
    lines += [f"| {d['shape']} | {d['cells']} | {d['holders']} | {d['estimate_iou']:.2f} | "
              f"{d['hull_iou']:.2f} | {d['verdicts']} |" for d in shapes]
    lines += ["", "| posterior of the call | calls | right | fraction right |", "|---|---|---|---|"]
    lines += [f"| {b['p']} | {b['calls']} | {b['right']} | "
              f"{b['right'] / b['calls'] if b['calls'] else float('nan'):.2f} |"
              for b in out["calibration"]]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--rows", action="store_true", help="print every run's row too")
    a = ap.parse_args()
    t0 = time.time()
    js = jobs(a.seeds)
    with ProcessPoolExecutor(a.workers) as ex:
        rows = list(ex.map(one, js, chunksize=1))
    out = {"command": f"bench/open_set.py --seeds {a.seeds} --workers {a.workers}",
           "polyomino_seed": SEED, "shapes": SHAPES, **summarise(rows),
           "wall_s": round(time.time() - t0, 1)}
    shapes = per_shape(rows)
    out["drawn_shapes"] = shapes
    out["markdown"] = markdown(out, shapes)
    if a.rows:
        out["rows"] = [{k: v for k, v in r.items() if k != "calls"} for r in rows]
    print(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
