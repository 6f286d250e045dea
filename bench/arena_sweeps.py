"""The sweeps of docs/extensions.md (sim_backend/arena_presets.py:
`touchswarm sweep --preset sizes|obstacles|field` runs the same points).
Each writes OUT/<name>.csv and OUT/<name>.png (delivery rate, time to
delivery, IoU per point); one JSON line per preset on stdout and in
OUT/<name>.json.

    .venv/bin/python bench/arena_sweeps.py [--seeds 10] [--out arena-out]
        [--only sizes,obstacles,field] [--engine auto]
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

from sim_backend import arena_presets
from sim_backend.scenario import load
from sim_backend.sweep import read_csv, sweep, write_csv


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=arena_presets.SEEDS)
    ap.add_argument("--out", default="arena-out")
    ap.add_argument("--only", default=",".join(arena_presets.PRESETS))
    ap.add_argument("--engine", default="auto")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in args.only.split(","):
        base, make = arena_presets.PRESETS[name]
        t0 = time.perf_counter()
        rows = sweep(make(), range(1, args.seeds + 1), base=load(base), engine=args.engine,
                     overrides={"maxTicks": arena_presets.MAX_TICKS})
        write_csv(rows, out / f"{name}.csv")
        saved = read_csv(out / f"{name}.csv")
        arena_presets.plots(saved, out, name)
        line = json.dumps({"experiment": name, "seeds": args.seeds,
                           "maxTicks": arena_presets.MAX_TICKS, "engine": args.engine,
                           "wall_s": round(time.perf_counter() - t0, 1),
                           "points": arena_presets.summarise(saved)})
        (out / f"{name}.json").write_text(line + "\n")
        print(line, flush=True)


if __name__ == "__main__":
    main()
