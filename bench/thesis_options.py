"""The four Appendix A options, each against the current default.

Each option alone on the default scenario (probeSelf, firstMove,
uphillHeading "netlogo"; wrap true, NetLogo's wrapping world), all four
together, and the built-in `netlogo` scenario (every option the thesis's),
at fieldDefiance 0 and 4, both movement models, until converged, maxTicks
5000, seeds 1..N, the soa engine. For every cell: runs, stalls (not
converged by maxTicks) and the median go iterations to convergence
(`converged_tick`) of the converged runs. Prints JSON; with --markdown also
the table docs/thesis-reproduction.md carries (between its markers; a test
runs this script in a tiny mode and checks the table's rows and columns).

    .venv/bin/python bench/thesis_options.py [--seeds 30] [--activation sync|netlogo]
        [--engine soa|reference|auto] [--max-ticks 5000] [--workers N] [--markdown]

--workers 0 runs in this process.
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

# name, base scenario, overrides, the thesis's rule (Appendix A), our default
VARIANTS = (
    ("(default)", "default", {}, "-", "-"),
    ("`probeSelf = \"netlogo\"`", "default", {"probeSelf": "netlogo"},
     "HeadCarefully: `any? turtles-on (patch-at-heading-and-distance heading 1)` counts the "
     "robot itself", "`skip`"),
    ("`firstMove = \"netlogo\"`", "default", {"firstMove": "netlogo"},
     "go: `RandomHead FindObject ...`: move, then look", "`look`"),
    ("`uphillHeading = \"netlogo\"`", "default", {"uphillHeading": "netlogo"},
     "FollowField: `set heading uphill field`, NetLogo 3's reporter towards the winner",
     "`octant`"),
    ("`wrap = true`", "default", {"wrap": True},
     "NetLogo's default world wraps; 3.7: \"a grid of 18 x 18 square patches\"",
     "bounded, -18..18"),
    ("all four", "default", {"probeSelf": "netlogo", "firstMove": "netlogo",
                             "uphillHeading": "netlogo", "wrap": True}, "-", "-"),
    ("`--scenario netlogo`", "netlogo", {},
     "every rule the thesis's, `activation = \"netlogo\"`", "-"),
)
DEFIANCE = (0, 4)
MODELS = ("firefly", "ant")


def cell(rows):
    ticks = [int(r["converged_tick"]) for r in rows if r["converged_tick"] is not None]
    return {"runs": len(rows), "stalled": len(rows) - len(ticks),
            "median": statistics.median(ticks) if ticks else None}


def main(argv=None):
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=30)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--engine", choices=("auto", "soa", "reference"), default="auto")
    ap.add_argument("--max-ticks", type=int, default=5000)
    ap.add_argument("--activation", choices=("sync", "netlogo"), default=None,
                    help="force every variant's activation (default: each scenario's own)")
    ap.add_argument("--markdown", action="store_true")
    a = ap.parse_args(argv)
    seeds = list(range(1, a.seeds + 1))
    out = {"seeds": a.seeds, "maxTicks": a.max_ticks, "until": "converged",
           "activation": a.activation or "each scenario's", "cells": []}
    t0 = time.perf_counter()
    for name, base_name, opts, _, _ in VARIANTS:
        base = scenario.load(base_name)
        over = {"maxTicks": a.max_ticks, **opts}
        if a.activation:
            over["activation"] = a.activation
        points = [Point("options", (("movementModel", m), ("fieldDefiance", fd)))
                  for m in MODELS for fd in DEFIANCE]
        if a.workers:
            with ProcessPoolExecutor(a.workers) as ex:
                rows = sweep.sweep(points, seeds, base=base, executor=ex, until="converged",
                                   overrides=over, chunk_size=64, engine=a.engine)
        else:
            rows = sweep.sweep(points, seeds, base=base, until="converged", overrides=over,
                               engine=a.engine)
        for m in MODELS:
            for fd in DEFIANCE:
                got = [r for r in rows if r["movementModel"] == m and int(r["fieldDefiance"]) == fd]
                out["cells"].append({"variant": name, "movementModel": m, "fieldDefiance": fd,
                                     **cell(got)})
    out["wall_s"] = round(time.perf_counter() - t0, 1)
    print(json.dumps(out, indent=1))
    if a.markdown:
        print(markdown(out))
    return 0


def markdown(out):
    """The options table: per option, the thesis's rule and our default, then
    the median go iterations (stalled/runs) at each model and fieldDefiance."""
    head = (["option", "thesis's rule (Appendix A)", "our default"]
            + [f"{m} fD {fd}: median (stalled/runs)" for m in MODELS for fd in DEFIANCE])
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name, _, _, rule, default in VARIANTS:
        row = [name, rule, default]
        for m in MODELS:
            for fd in DEFIANCE:
                c = next(c for c in out["cells"] if c["variant"] == name
                         and c["movementModel"] == m and c["fieldDefiance"] == fd)
                med = "-" if c["median"] is None else f"{c['median']:g}"
                row.append(f"{med} ({c['stalled']}/{c['runs']})")
        lines.append("| " + " | ".join(row) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    sys.exit(main())
