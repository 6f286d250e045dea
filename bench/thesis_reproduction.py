"""Wall time of the full thesis reproduction (`touchswarm sweep --thesis`,
the thesis behaviour's study "thesis" in firmware_logic/behaviours/thesis/studies.py).

Every graph and figure of chapter 5, both movement models, 150 seeds per
point, one worker process per core, either activation (sync, the default,
or netlogo, NetLogo's sequential `ask`) in the struct-of-arrays engine
(`--engine auto`; compiled first if the disk cache lacks it, and the
compile is not in the wall time). Prints JSON.

    .venv/bin/python bench/thesis_reproduction.py [--seeds N] [--out DIR]
        [--activation sync|netlogo]
"""

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from sim_backend import studies, sweep  # noqa: E402

STUDY = studies.get("thesis", "thesis")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=STUDY.seeds)
    ap.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--out", type=Path, default=Path("thesis-out"))
    ap.add_argument("--activation", choices=("sync", "netlogo"), default="sync")
    a = ap.parse_args()
    points = list(STUDY.points)
    seeds = list(range(1, a.seeds + 1))
    total = len(points) * len(seeds)
    chunk = max(16, min(512, -(-total // (a.workers * 6))))
    overrides = {**dict(STUDY.overrides), "activation": a.activation}
    t0 = time.perf_counter()
    compiled = sweep.warm(sweep.point_scenarios(points, overrides=overrides))
    warm_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    with ProcessPoolExecutor(a.workers) as ex:
        rows = sweep.sweep(points, seeds, executor=ex, until=STUDY.until,
                           overrides=overrides, chunk_size=chunk,
                           compile_first=False)       # warmed above, timed apart
    t_runs = time.perf_counter() - t0
    sweep.write_csv(rows, a.out / "sweep.csv")
    pngs = studies.draw(STUDY, rows, a.out)
    t_all = time.perf_counter() - t0
    robot_ticks = sum(int(r["ticks"]) * int(r["agents"]) for r in rows)
    print(json.dumps({
        "runs": len(rows), "points": len(points), "seeds_per_point": len(seeds),
        "workers": a.workers, "cpu_count": os.cpu_count(), "until": STUDY.until,
        "activation": a.activation,
        "maxTicks": overrides["maxTicks"],
        "censored_runs": sum(1 for r in rows if r["converged_tick"] is None),
        "robot_ticks": robot_ticks,
        "engine_start_s": round(warm_s, 2), "compiled": compiled,
        "wall_s_runs": round(t_runs, 2), "wall_s_total": round(t_all, 2),
        "robot_ticks_per_s": round(robot_ticks / t_runs),
        "plots": [str(p) for p in pngs],
    }, indent=2))


if __name__ == "__main__":
    main()
