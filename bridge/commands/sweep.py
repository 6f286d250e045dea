"""`touchswarm sweep`: a grid of scenario parameters x seeds (BehaviourSpace)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from bridge.commands.paths import path_arg
from bridge.errors import UsageError
from sim_backend.sweep import ENGINES


def register(sub) -> None:
    p = sub.add_parser(
        "sweep", help="run a grid of parameters x seeds; tidy CSV and the thesis's plots",
        description="Run every grid point with every seed (the thesis's BehaviourSpace) in the "
                    "vectorised engine, spread over an executor; write one CSV row per run "
                    "(every parameter and every measured figure) and PNG plots.",
        epilog="examples:\n"
               "  touchswarm sweep --grid fieldDefiance=0,2,4,8 --grid movementModel=firefly,ant "
               "--seeds 150\n"
               "  touchswarm sweep --thesis --out thesis-out\n"
               "  touchswarm sweep --grid sigRadius=3,5,7 --seeds 101-200 --executor "
               "dask://10.0.0.5:8786\n"
               "\nEverything is checked before the first run: keys and values, seeds (distinct, "
               "0..1000002),\nthe output directory and the executor. Exit 0 when every run "
               "finished, 2 on bad input.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", default="default", metavar="NAME|FILE",
                   help="base scenario every point starts from (default: %(default)s)")
    p.add_argument("--grid", action="append", default=[], metavar="KEY=V1,V2,...",
                   help="a scenario key and its distinct values (repeatable, once per key; "
                        "the grid is their product)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key for every point (repeatable, once per key, "
                        "not a --grid key)")
    p.add_argument("--seeds", default=None, metavar="N|A-B|A,B,...",
                   help="seeds: a count N (seeds 1..N), a range A-B (A <= B) or a list of "
                        "distinct seeds, each in 0..1000002 (default: 20; --thesis: 150)")
    p.add_argument("--preset", choices=("faults", "breeds"),
                   help="faults: the robustness sweep of issue 12 (each fault alone at rates "
                        "0-0.5, and 25%% dead + 10%% non-complying + 10%% random; 20 seeds, "
                        "until delivered); faults.png plots delivery rate and time. breeds: "
                        "0, 5, 10, 15, 20 ants in a swarm of 20 with fireflies, 30 seeds, "
                        "until converged; breeds.png")
    p.add_argument("--thesis", action="store_true",
                   help="reproduce every graph and figure of the thesis's chapter 5 "
                        "(150 seeds per point, both movement models, until convergence)")
    p.add_argument("--until", choices=["delivered", "converged"], default=None,
                   help="stop each run when the object is home or when power first reaches "
                        "its weight (default: delivered; --thesis: converged)")
    p.add_argument("--engine", choices=ENGINES, default="auto",
                   help="auto (default): the hand-vectorised engine for the thesis behaviour, "
                        "the batch engine compiled from the behaviour's source for any other; "
                        "batch: always the compiled engine (compiles for ~15 s per process); "
                        "vector: thesis only; reference: the per-robot engine")
    p.add_argument("--executor", default="processes", metavar="SPEC",
                   help="processes[:N] (default: one per core), inline, or dask://HOST:PORT "
                        "(a dask.distributed scheduler)")
    p.add_argument("--chunk", type=int, default=None, metavar="RUNS",
                   help="runs per task, at least 1 (default: spread evenly, at most 512)")
    p.add_argument("--out", type=path_arg, default=Path("sweep-out"), metavar="DIR",
                   help="directory (created if missing) for sweep.csv and the PNGs "
                        "(default: %(default)s)")
    p.add_argument("--no-plots", action="store_true", help="write the CSV only")
    p.add_argument("--json", action="store_true", help="print a JSON summary line")
    p.set_defaults(func=cmd_sweep)


def _seeds(text: str) -> list[int]:
    """--seeds as a list of distinct seeds in the valid range."""
    from sim_backend.scenario import SEED_MAX, SEED_MIN
    form = "expected a count N, a range A-B or a list A,B,... of seeds in " \
           f"{SEED_MIN}..{SEED_MAX}"
    try:
        if "," in text:
            seeds = [int(v) for v in text.split(",") if v.strip()]
        elif "-" in text.strip()[1:]:
            a, b = (int(v) for v in text.split("-", 1))
            if a > b:
                raise UsageError(f"--seeds {text}: the range is empty (A > B); "
                                 f"expected A-B with A <= B, e.g. {b}-{a}")
            seeds = list(range(a, b + 1))
        else:
            n = int(text)
            if not 1 <= n <= SEED_MAX:
                raise UsageError(f"--seeds {text}: a count must be 1..{SEED_MAX} "
                                 f"(seeds 1..N); {form}")
            seeds = list(range(1, n + 1))
    except ValueError as err:
        if isinstance(err, UsageError):
            raise
        raise UsageError(f"--seeds {text!r}: {form}") from None
    if not seeds:
        raise UsageError(f"--seeds {text!r}: no seeds; {form}")
    for s in seeds:
        if not SEED_MIN <= s <= SEED_MAX:
            raise UsageError(f"--seeds {text}: seed {s} is outside {SEED_MIN}..{SEED_MAX} "
                             "(the firmware RNG takes seeds modulo 1000003)")
    dup = next((s for i, s in enumerate(seeds) if s in seeds[:i]), None)
    if dup is not None:
        raise UsageError(f"--seeds {text}: seed {dup} is listed twice; a repeated seed is "
                         "the same run again, give each seed once")
    return seeds


def _grid(items: list[str]) -> dict:
    from bridge.commands.run import parse_value
    grid: dict = {}
    for item in items:
        key, eq, values = item.partition("=")
        key = key.strip()
        if not eq or not key or not values.strip():
            raise UsageError(f"--grid {item!r}: expected KEY=V1,V2,..., "
                             "e.g. --grid fieldDefiance=0,2,4")
        if key in grid:
            raise UsageError(f"--grid {key} given twice; put all its values in one "
                             f"--grid {key}=V1,V2,...")
        grid[key] = [parse_value(v.strip()) for v in values.split(",") if v.strip()]
    return grid


def cmd_sweep(args: argparse.Namespace) -> int:
    from bridge.commands.run import parse_overrides
    from sim_backend import scenario, sweep

    base = scenario.load(args.scenario)
    overrides = parse_overrides(args.set)
    if args.preset and (args.thesis or args.grid):
        raise UsageError(f"--preset {args.preset} runs its own grid; drop --thesis and --grid")
    if args.preset == "faults":
        from sim_backend import robustness
        points = robustness.fault_points()
        seeds = _seeds(args.seeds) if args.seeds else list(range(1, robustness.PRESET_SEEDS + 1))
        until = args.until or "delivered"
        overrides.setdefault("maxTicks", robustness.PRESET_MAX_TICKS)
        overrides.setdefault("faultWindow", robustness.PRESET_FAULT_WINDOW)
        grid = {}
    elif args.preset == "breeds":
        from sim_backend import robustness
        points = robustness.breed_points()
        seeds = _seeds(args.seeds) if args.seeds else list(range(1, robustness.BREED_SEEDS + 1))
        until = args.until or "converged"
        overrides.setdefault("maxTicks", 5000)
        grid = {}
    elif args.thesis:
        if args.grid:
            raise UsageError("--thesis runs its own grid; drop --grid")
        points = sweep.thesis_points()
        seeds = _seeds(args.seeds) if args.seeds else list(range(1, sweep.THESIS_SEEDS + 1))
        until = args.until or sweep.THESIS_UNTIL
        overrides.setdefault("maxTicks", sweep.THESIS_MAX_TICKS)
    else:
        if not args.grid:
            raise UsageError("give at least one --grid KEY=V1,V2,... (or --thesis)")
        grid = _grid(args.grid)
        both = sorted(set(grid) & set(overrides))
        if both:
            raise UsageError(f"--set {both[0]} and --grid {both[0]} both given; the grid "
                             "would override --set: give the key in one of them")
        points = sweep.grid_points(grid)
        seeds = _seeds(args.seeds) if args.seeds else list(range(1, 21))
        until = args.until or "delivered"
    if args.chunk is not None and args.chunk < 1:
        raise UsageError(f"--chunk {args.chunk}: expected at least 1 run per task")
    # every check that can refuse the sweep runs before the first run
    sweep.validate_points(points, base, overrides)
    from bridge.commands.paths import check_out_dir
    check_out_dir(args.out, "--out")
    try:
        executor, close = sweep.executor_from_spec(args.executor)
    except ValueError as err:
        raise UsageError(str(err)) from None
    total = len(points) * len(seeds)
    workers = getattr(executor, "_max_workers", 2) or 2
    chunk = args.chunk or max(16, min(512, -(-total // (workers * 6))))
    from tqdm import tqdm
    bar = tqdm(total=total, unit="run", desc="sweep", disable=not sys.stderr.isatty())
    t0 = time.perf_counter()
    try:
        rows = sweep.sweep(points, seeds, base=base, engine=args.engine, executor=executor,
                           until=until, chunk_size=chunk, overrides=overrides,
                           progress=bar.update)
    finally:
        bar.close()
        close()
    wall = time.perf_counter() - t0
    csv_path = sweep.write_csv(rows, args.out / "sweep.csv")
    pngs = []
    if not args.no_plots:
        from sim_backend import plots
        if args.preset == "faults":
            from sim_backend import robustness
            pngs = robustness.fault_plots(rows, args.out)
        elif args.preset == "breeds":
            from sim_backend import robustness
            pngs = robustness.breed_plots(rows, args.out)
        elif args.thesis:
            pngs = plots.thesis_plots(rows, args.out)
        else:
            pngs = plots.grid_plots(rows, list(grid), args.out)
    info = {"runs": len(rows), "points": len(points), "seeds": len(seeds), "engine": args.engine,
            "executor": args.executor, "until": until, "wall_s": round(wall, 3),
            "csv": str(csv_path), "plots": [str(p) for p in pngs]}
    if args.json:
        print(json.dumps(info, sort_keys=True))
    else:
        print(f"{len(rows)} runs ({len(points)} points x {len(seeds)} seeds, {args.engine} "
              f"engine, until {until}) in {wall:.1f} s")
        print(f"  {csv_path}")
        for p in pngs:
            print(f"  {p}")
    return 0
