"""Issue 31's four Appendix A options, each against the current default.

Each option alone on the default scenario (probeSelf, firstMove,
uphillHeading "netlogo"; wrap true, NetLogo's wrapping world), all four
together, and the built-in `netlogo` scenario (every option the thesis's),
at fieldDefiance 0 and 4, both movement models, until converged, maxTicks
5000, seeds 1..N, the soa engine. For every cell: runs, stalls (not
converged by maxTicks) and the median go iterations to convergence
(`converged_tick`) of the converged runs. Prints JSON; with --markdown also
the table docs/thesis-reproduction.md carries.

    .venv/bin/python bench/thesis_options.py [--seeds 30] [--activation sync|netlogo]
        [--markdown]
"""

import argparse
import json
import os
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from sim_backend import scenario, sweep  # noqa: E402
from sim_backend.sweep import Point  # noqa: E402

VARIANTS = (
    ("default", "default", {}),
    ("probeSelf", "default", {"probeSelf": "netlogo"}),
    ("firstMove", "default", {"firstMove": "netlogo"}),
    ("uphillHeading", "default", {"uphillHeading": "netlogo"}),
    ("wrap", "default", {"wrap": True}),
    ("all four", "default", {"probeSelf": "netlogo", "firstMove": "netlogo",
                             "uphillHeading": "netlogo", "wrap": True}),
    ("netlogo scenario", "netlogo", {}),
)
DEFIANCE = (0, 4)
MODELS = ("firefly", "ant")


def cell(rows):
    ticks = [int(r["converged_tick"]) for r in rows if r["converged_tick"] is not None]
    return {"runs": len(rows), "stalled": len(rows) - len(ticks),
            "median": statistics.median(ticks) if ticks else None}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--activation", choices=("sync", "netlogo"), default=None,
                    help="force every variant's activation (default: each scenario's own)")
    ap.add_argument("--markdown", action="store_true")
    a = ap.parse_args()
    seeds = list(range(1, a.seeds + 1))
    out = {"seeds": a.seeds, "maxTicks": 5000, "until": "converged",
           "activation": a.activation or "each scenario's", "cells": []}
    t0 = time.perf_counter()
    for name, base_name, opts in VARIANTS:
        base = scenario.load(base_name)
        over = {"maxTicks": 5000, **opts}
        if a.activation:
            over["activation"] = a.activation
        points = [Point(name, (("movementModel", m), ("fieldDefiance", fd)))
                  for m in MODELS for fd in DEFIANCE]
        with ProcessPoolExecutor(a.workers) as ex:
            rows = sweep.sweep(points, seeds, base=base, executor=ex, until="converged",
                               overrides=over, chunk_size=64)
        for m in MODELS:
            for fd in DEFIANCE:
                got = [r for r in rows if r["movementModel"] == m and int(r["fieldDefiance"]) == fd]
                out["cells"].append({"variant": name, "movementModel": m, "fieldDefiance": fd,
                                     **cell(got)})
    out["wall_s"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(out, indent=1))
    if a.markdown:
        print(markdown(out))


def markdown(out):
    head = ["option"] + [f"{m} fD {fd}" for m in MODELS for fd in DEFIANCE]
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, _, _ in VARIANTS:
        row = [name]
        for m in MODELS:
            for fd in DEFIANCE:
                c = next(c for c in out["cells"] if c["variant"] == name
                         and c["movementModel"] == m and c["fieldDefiance"] == fd)
                row.append(f"{c['median']} ({c['stalled']}/{c['runs']} stalled)")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    main()
