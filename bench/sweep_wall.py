"""Wall clock where a user waits: a `touchswarm sweep` against the Mesa 3
port of bench/mesa_baseline.py doing the same runs, and `touchswarm run`
against its floor. Every figure is a fresh interpreter timed from outside
(its imports, set-up and exit included), as a user meets it.

- "fresh_sweep": `touchswarm sweep --seeds 20` of the Mesa port's scenario
  (20 robots, worldSize 18, its parameters; --no-plots) with an empty
  `$TOUCHSWARM_CACHE` (a fresh machine, or a behaviour just edited: the
  runs start in the reference engine while the soa step compiles in the
  background), beside the Mesa port's 20 runs in one process. The
  compile the sweep leaves running is ended (by its pid, which the sweep
  names on stderr) before anything else is timed.
- "sweep_500": the same sweep with `--seeds 500` on the warm cache (the
  step on disk), beside the Mesa port's wall time for 500 runs: measured on
  --mesa-runs of them in one process and scaled (all 500 with
  --mesa-runs 500); "sweep_N" for each other N of `--sweep-runs 500,20`
  (a small sweep: in the sweep's own process, sim_backend.sweep's
  SMALL_SWEEP_ROBOTS). Both in one process each: the sweep's default executor
  uses every core, so the Mesa figure is given for one process and for as
  many processes as the sweep used (its wall time divided by them, the best
  a process pool could do).
- "run": `touchswarm run --json` (the default scenario, seed 1, reference
  engine) against its floor, `python -c "import numpy"` plus the same
  `main(["run", "--json"])` timed inside a process that ran it once already
  (every module imported, every per-process cache filled): what the command
  adds to its floor is its start-up alone. Each of the three timed after one
  untimed call; `--tree DIR` (repeatable) times another source tree's
  command and in-process run, and its warm sweep, beside this one's (e.g.
  an export of an older commit: `git archive COMMIT | tar -x -C /tmp/old`),
  in rounds that interleave the trees (every other round in the other
  order; "rounds_load": the load average after each round).

Every child reads and writes bytecode as a user's install does
(cli_startup.user_env), even where PYTHONDONTWRITEBYTECODE is set. Medians
of --reps (the sweeps: one each unless --reps; the run: at least 3).
Prints one JSON.

    .venv/bin/python bench/sweep_wall.py [--reps N] [--mesa-runs N] [--sweep-runs N[,N...]] [--skip-fresh]
                                         [--skip-run] [--tree DIR]
    .venv/bin/python bench/sweep_wall.py --run-only [--reps N] [--tree DIR]
"""

from __future__ import annotations

import argparse
import json
import os
import re
import resource
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from cli_startup import user_env

ROOT = Path(__file__).resolve().parents[1]
BENCH = Path(__file__).resolve().parent
# what the `touchswarm` console script runs (bridge.cli.entry; a tree from
# before it had main)
CLI = ("import sys; from bridge import cli; "
       "sys.exit(getattr(cli, 'entry', cli.main)(sys.argv[1:]))")

MESA = r"""
import sys, time
sys.path.insert(0, sys.argv[1])
import mesa_baseline as m
n, act = int(sys.argv[2]), sys.argv[3]
side = m.Side()
t, c = time.perf_counter(), time.process_time()
for seed in range(1, n + 1):
    side.mesa_run(20, 18, seed, act, 20000)
print(time.perf_counter() - t, time.process_time() - c)
"""

RUN_FLOOR = r"""
import contextlib, io, sys, time
from bridge.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    main(["run", "--json"])                      # everything imported, once
t, c = time.perf_counter(), time.process_time()
with contextlib.redirect_stdout(io.StringIO()):
    main(["run", "--json"])
print(time.perf_counter() - t, time.process_time() - c)
"""


def scenario_args(activation: str) -> list[str]:
    """--set options making the sweep's scenario the Mesa port's."""
    sys.path.insert(0, str(BENCH))
    import mesa_baseline as m
    keys = {"agents": 20, "worldSize": 18, "maxTicks": 20000, "activation": activation,
            **m.PARAMS}
    out = []
    for k, v in keys.items():
        out += ["--set", f"{k}={v}"]
    return out


ENV: dict[str, str] = dict(os.environ)     # every child's (main sets user_env)
CPU = [0.0]        # the CPU seconds of the last child (and the children it waited for)


def wall(argv: list[str], env: dict | None = None, cwd: Path = ROOT
         ) -> tuple[float, str, str]:
    """Wall seconds of one child process, its stdout and its stderr; its CPU
    seconds (user + system, its worker processes included) in CPU[0]."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t = time.perf_counter()
    p = subprocess.run(argv, cwd=cwd, env=ENV if env is None else env, stdout=subprocess.PIPE,
                       stderr=subprocess.PIPE, text=True)
    w = time.perf_counter() - t
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    CPU[0] = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if p.returncode != 0:
        raise SystemExit(f"bench/sweep_wall.py: {' '.join(argv[:4])} ... failed "
                         f"({p.returncode}): {p.stderr.strip().splitlines()[-1:]}")
    return w, p.stdout, p.stderr


def sweep(seeds: int, activation: str, out: Path, env: dict | None = None,
          tree: Path = ROOT) -> tuple[float, str]:
    """Wall seconds of the sweep (of `tree`'s sources) and its stderr."""
    w, _, err = wall([sys.executable, "-c", CLI, "sweep", "--seeds", str(seeds), "--no-plots",
                 "--overwrite", "--out", str(out), *scenario_args(activation)], env, tree)
    return w, err


def end_background_compile(stderr: str) -> int | None:
    """End the soa compile a sweep left running (it names its pid)."""
    m = re.search(r"pid (\d+)", stderr)
    if not m:
        return None
    pid = int(m.group(1))
    try:
        os.kill(pid, signal.SIGTERM)
    except ProcessLookupError:
        return None
    return pid


def mesa(runs: int, activation: str, scale_to: int | None = None) -> tuple[float, float]:
    """Wall and CPU seconds of a process running the Mesa port's seeds
    1..runs; with scale_to, its runs' share scaled to that many runs
    (start-up as measured)."""
    return mesa_scaled(runs, activation, [scale_to or runs])[0]


def mesa_scaled(runs: int, activation: str, sizes: list[int]) -> list[tuple[float, float]]:
    """mesa(runs, activation, n) for every n of `sizes`, from one process."""
    w, out, _ = wall([sys.executable, "-c", MESA, str(BENCH), str(runs), activation])
    inside, inside_cpu = map(float, out.strip().splitlines()[-1].split())
    return [(w - inside + inside * n / runs, CPU[0] - inside_cpu + inside_cpu * n / runs)
            for n in sizes]


def workers() -> int:
    return len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()


def sizes(text: str) -> list[int]:
    """--sweep-runs: run counts, each at least 1."""
    try:
        out = [int(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: expected N or N,N,... runs") from None
    if not out or min(out) < 1:
        raise argparse.ArgumentTypeError(f"{text!r}: every count must be at least 1 run")
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=1, help="times per figure (default: 1)")
    ap.add_argument("--mesa-runs", type=int, default=40,
                    help="Mesa runs timed for the 500-run figure, scaled to 500 (default: 40)")
    ap.add_argument("--activation", choices=("sync", "netlogo"), default="sync")
    ap.add_argument("--sweep-runs", type=sizes, default=[500], metavar="N[,N...]",
                    help="runs of each warm-cache sweep, its figure \"sweep_N\" (default: 500; "
                         "e.g. 500,20 for a small sweep too)")
    ap.add_argument("--skip-fresh", action="store_true", help="no fresh-cache sweep")
    ap.add_argument("--run-only", action="store_true", help="no sweep: the run against its floor")
    ap.add_argument("--skip-run", action="store_true", help="no run against its floor")
    ap.add_argument("--tree", action="append", default=[], type=Path,
                    help="another source tree whose run (and warm sweep) to time beside "
                         "this one's")
    a = ap.parse_args(argv)
    act = a.activation
    out: dict = {"cpus": os.cpu_count(), "workers": workers(), "load_before": os.getloadavg()[0],
                 "activation": act}
    with tempfile.TemporaryDirectory() as tmp:
        tmpd = Path(tmp)
        ENV.clear()
        ENV.update(user_env(tmpd / "pycache"))
        if not (a.run_only or a.skip_fresh):
            rows = []
            for k in range(a.reps):
                env = {**ENV, "TOUCHSWARM_CACHE": str(tmpd / f"cache{k}")}
                w, err = sweep(20, act, tmpd / f"fresh{k}", env)
                cpu = CPU[0]
                end_background_compile(err)
                rows.append((w, cpu) + mesa(20, act))
            s, sc, m, mc = (statistics.median(r[j] for r in rows) for j in range(4))
            out["fresh_sweep"] = {
                "runs": 20, "cache": "empty (soa compiles in the background; ended after)",
                "sweep_wall_s": round(s, 2), "mesa_wall_s": round(m, 2),
                "sweep_cpu_s": round(sc, 2), "mesa_cpu_s": round(mc, 2),
                "sweep_over_mesa": round(s / m, 2), "sweep_over_mesa_cpu": round(sc / mc, 2),
                "target": "<= 1.5"}
        if not a.run_only:
            warm_sweeps(a, out, tmpd)
        trees = {"this": ROOT, **{str(t): t.resolve() for t in a.tree}}
        if not a.skip_run:
            out.update(run_vs_floor(trees, max(3, a.reps)))
    out["load_after"] = os.getloadavg()[0]
    print(json.dumps(out, indent=1))
    return 0


def warm_sweeps(a: argparse.Namespace, out: dict, tmpd: Path) -> None:
    """out["sweep_N"] (and "sweep_N TREE" for each --tree) for every N of
    --sweep-runs: the warm-cache sweep against the Mesa port, the trees'
    sweeps and the Mesa port's runs interleaved in rounds so that load
    hits them alike."""
    act = a.activation
    trees = {"this": ROOT, **{str(t): t.resolve() for t in a.tree}}
    for tree in trees.values():
        sweep(1, act, tmpd / "warmup", tree=tree)        # the step loaded, text kept
    rows: dict[tuple[int, str], list] = {(n, label): [] for n in a.sweep_runs for label in trees}
    loads = []
    for k in range(a.reps):
        mesa_k = mesa_scaled(a.mesa_runs, act, a.sweep_runs)
        # the trees in turn, every other round backwards (ABBA): the sweep
        # run second in a round read lower, as much as a change moves it
        order = list(trees.items())[::-1 if k % 2 else 1]
        for n, m in zip(a.sweep_runs, mesa_k):
            for label, tree in order:
                w = sweep(n, act, tmpd / f"big{k}", tree=tree)[0]
                rows[(n, label)].append((w, CPU[0]) + m)
        loads.append(round(os.getloadavg()[0], 1))
    out["rounds_load"] = loads
    for (n, label), got in rows.items():
        s, sc, m1, mc = (statistics.median(r[j] for r in got) for j in range(4))
        out[f"sweep_{n}" if label == "this" else f"sweep_{n} {label}"] = {
            "runs": n, "cache": "warm", "sweep_wall_s": round(s, 2),
            "sweep_cpu_s": round(sc, 2), "mesa_cpu_s": round(mc, 1),
            "speedup_cpu": round(mc / sc, 1),
            "mesa_runs_timed": a.mesa_runs, "mesa_wall_s_one_process": round(m1, 1),
            "mesa_wall_s_per_worker": round(m1 / out["workers"], 1),
            "speedup_one_process": round(m1 / s, 1),
            "speedup_per_worker": round(m1 / out["workers"] / s, 1), "target": ">= 10",
            "rounds_wall_s": [round(r[0], 2) for r in got],
            "rounds_cpu_s": [round(r[1], 2) for r in got]}


def run_vs_floor(trees: dict[str, Path], reps: int) -> dict:
    """"run" (and "run TREE" for each other tree): the command's wall time
    against its floor's, the three interleaved, the first round untimed (it
    writes the bytecode); the same in CPU seconds, which a loaded machine
    blurs less."""
    rows: dict[str, list] = {label: [] for label in trees}
    for k in range(reps + 1):
        for label, tree in trees.items():
            run = wall([sys.executable, "-c", CLI, "run", "--json"], cwd=tree)[0], CPU[0]
            numpy = wall([sys.executable, "-c", "import numpy"], cwd=Path("/"))[0], CPU[0]
            inside = tuple(map(float, wall([sys.executable, "-c", RUN_FLOOR], cwd=tree)[1]
                                .split()))
            if k:
                rows[label].append(run + numpy + inside)
    out = {}
    for label, got in rows.items():
        run, run_cpu, numpy, numpy_cpu, inside, inside_cpu = (
            statistics.median(r[k] for r in got) for k in range(6))
        out["run" if label == "this" else f"run {label}"] = {
            "touchswarm_run_wall_s": round(run, 3), "import_numpy_wall_s": round(numpy, 3),
            "run_in_process_s": round(inside, 3), "floor_s": round(numpy + inside, 3),
            "over_floor": round(run / (numpy + inside), 2), "target": "<= 1.2",
            "touchswarm_run_cpu_s": round(run_cpu, 3), "import_numpy_cpu_s": round(numpy_cpu, 3),
            "run_in_process_cpu_s": round(inside_cpu, 3),
            "over_floor_cpu": round(run_cpu / (numpy_cpu + inside_cpu), 2)}
    return out


if __name__ == "__main__":
    sys.exit(main())
