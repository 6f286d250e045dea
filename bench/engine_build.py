"""What a warm soa engine costs before its first tick, and whether a second
worker helps a small sweep.

Two parts, one JSON object:

- "build": CPU seconds (`time.process_time`, this process pinned to one
  core) to build a `SoaEngine` of the default (thesis) scenario on a warm
  cache, 1 run and 17 runs of 20 robots, median of --reps builds each:
  `transform` re-generates the text (what every build did before the text
  was kept: an empty `generated/` folder), `kept_on_disk` reads the text a
  first build left in the cache folder (a new worker process, a new
  sweep), `kept_in_memory` a second build in the same process. numba is
  imported and the step loaded before any of them (once per process
  anyway), so the figures are the build's own.
- "sweep": wall seconds of `sweep.sweep` over 20 and 200 runs (grid
  fieldDefiance=2, default scenario, engine auto on a warm cache), each in
  a fresh interpreter as the CLI runs it (its own numba import and step
  load), inline (one process), 1 worker process and 2 worker processes,
  chunks as the sweep sizes them (`sweep.chunk_runs`) unless --chunk;
  the configurations interleaved over --reps rounds so a busy neighbour
  slows them alike; medians. `--tree DIR` runs the same from another
  source tree too (e.g. `git archive COMMIT | tar -x -C DIR`), with the
  chunk its CLI chose (16-run minimum, six chunks per worker).

    .venv/bin/python bench/engine_build.py [--reps N] [--tree DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

BUILD = r"""
import json, os, statistics, sys, time
os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
import numba  # noqa: F401  (imported once per process whatever the build does)
from sim_backend.batch import soa
from sim_backend.scenario import validate
reps = int(sys.argv[1])
sc = validate({})
soa.SoaEngine([(sc, 1)]).step()          # the step loaded (or compiled) and the text kept
kept_dir = os.environ.get("TOUCHSWARM_CACHE")
empty = sys.argv[2]

def build(runs, where):
    if where != "kept_in_memory":
        soa._GENERATED.clear()
    if where == "transform":          # a folder without generated/: the transform runs
        os.environ["TOUCHSWARM_CACHE"] = os.path.join(empty, str(time.perf_counter_ns()))
    before = soa.transforms
    t = time.process_time()
    soa.SoaEngine([(sc, s) for s in range(1, runs + 1)])
    cpu = time.process_time() - t
    if kept_dir is None:
        os.environ.pop("TOUCHSWARM_CACHE", None)
    else:
        os.environ["TOUCHSWARM_CACHE"] = kept_dir
    assert (soa.transforms > before) == (where == "transform"), where
    return cpu

out = {}
for runs in (1, 17):
    got = {w: [] for w in ("transform", "kept_on_disk", "kept_in_memory")}
    for _ in range(reps):
        for w in got:
            got[w].append(build(runs, w))
    out[f"20x{runs}"] = {w: round(statistics.median(v), 4) for w, v in got.items()}
print(json.dumps(out))
"""

SWEEP = r"""
import json, sys, time
t0 = time.perf_counter()
from concurrent.futures import ProcessPoolExecutor
from sim_backend import sweep
runs, workers, chunk = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
points = sweep.grid_points({"fieldDefiance": [2]})
ex = ProcessPoolExecutor(workers) if workers else None
kw = {} if chunk == "auto" else {"chunk_size": int(chunk)}
rows = sweep.sweep(points, range(1, runs + 1), executor=ex, **kw)
if ex is not None:
    ex.shutdown()
assert len(rows) == runs and all(r["engine"] == "soa" for r in rows)
print(json.dumps({"wall": time.perf_counter() - t0,
                  "ticks": sorted(r["ticks"] for r in rows)[runs // 2]}))
"""


def child(code: str, args: list[str], cwd: Path, env: dict) -> tuple[dict, float]:
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    out = subprocess.run([sys.executable, "-c", code, *args], cwd=cwd, env=env,
                         capture_output=True, text=True)
    if out.returncode:
        raise SystemExit(f"bench child failed ({cwd}):\n{out.stderr[-2000:]}")
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return json.loads(out.stdout.strip().splitlines()[-1]), cpu


def old_chunk(runs: int, workers: int) -> int:
    """The chunk the CLI chose before `sweep.chunk_runs` (bridge/commands/sweep.py)."""
    return max(16, min(512, -(-runs // ((workers or 2) * 6))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--reps", type=int, default=3)
    ap.add_argument("--tree", type=Path, action="append", default=[])
    ap.add_argument("--chunk", default="auto", help="runs per chunk (default: the sweep's)")
    ap.add_argument("--skip-build", action="store_true")
    ap.add_argument("--skip-sweep", action="store_true")
    a = ap.parse_args()
    env = {**os.environ, "PYTHONPATH": str(ROOT), "OMP_NUM_THREADS": "1"}
    res: dict = {"cpu": "process CPU seconds (build); wall seconds (sweep)"}
    if not a.skip_build:
        # the step as this machine's cache holds it; the transform's builds
        # point the cache at empty folders (nothing compiles: the step is
        # already loaded in the process)
        with tempfile.TemporaryDirectory() as empty:
            res["build"], _ = child(BUILD, [str(a.reps), empty], ROOT, env)
    trees = [("this", ROOT)] + [(str(t), t.resolve()) for t in a.tree]
    configs = [] if a.skip_sweep else [(runs, w) for runs in (20, 200) for w in (0, 1, 2)]
    walls: dict = {}
    for _ in range(a.reps):
        for name, tree in trees:
            for runs, w in configs:
                chunk = a.chunk if name == "this" else str(old_chunk(runs, w))
                got, cpu = child(SWEEP, [str(runs), str(w), chunk], tree,
                                 {**env, "PYTHONPATH": str(tree)})
                walls.setdefault(name, {}).setdefault(f"{runs} runs", {}).setdefault(
                    {0: "inline", 1: "1 worker", 2: "2 workers"}[w], []).append(
                    (got["wall"], cpu))
    if configs:
        res["sweep"] = {
            name: {k: {w: {"wall_s": round(statistics.median(x[0] for x in v), 2),
                           "cpu_s": round(statistics.median(x[1] for x in v), 2)}
                       for w, v in d.items()} for k, d in by.items()}
            for name, by in walls.items()}
    for by in res.get("sweep", {}).values():
        for d in by.values():
            d["speedup_2_workers_vs_1"] = round(d["1 worker"]["wall_s"] / d["2 workers"]["wall_s"],
                                                2)
    res["load_avg"] = os.getloadavg()
    print(json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
