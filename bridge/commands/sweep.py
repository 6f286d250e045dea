"""`touchswarm sweep`: a grid of scenario parameters x seeds (BehaviourSpace)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from bridge.errors import UsageError


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
               "  touchswarm sweep --grid sigRadius=3,5,7 --executor dask://10.0.0.5:8786",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--scenario", default="default", metavar="NAME|FILE",
                   help="base scenario every point starts from (default: %(default)s)")
    p.add_argument("--grid", action="append", default=[], metavar="KEY=V1,V2,...",
                   help="a scenario key and its values (repeatable; the grid is their product)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key for every point (repeatable)")
    p.add_argument("--seeds", default=None, metavar="N|A-B|A,B,...",
                   help="seeds: a count N (1..N), a range A-B or a list (default: 20; "
                        "--thesis: 150)")
    p.add_argument("--thesis", action="store_true",
                   help="reproduce every graph and figure of the thesis's chapter 5 "
                        "(150 seeds per point, both movement models, until convergence)")
    p.add_argument("--until", choices=["delivered", "converged"], default=None,
                   help="stop each run when the object is home or when power first reaches "
                        "its weight (default: delivered; --thesis: converged)")
    p.add_argument("--engine", choices=["vector", "reference"], default="vector",
                   help="vectorised engine (default) or the per-robot reference engine")
    p.add_argument("--executor", default="processes", metavar="SPEC",
                   help="processes[:N] (default: one per core), inline, or dask://HOST:PORT "
                        "(a dask.distributed scheduler)")
    p.add_argument("--chunk", type=int, default=None, metavar="RUNS",
                   help="runs per task (default: spread evenly, at most 512)")
    p.add_argument("--out", type=Path, default=Path("sweep-out"), metavar="DIR",
                   help="where sweep.csv and the PNGs go (default: %(default)s)")
    p.add_argument("--no-plots", action="store_true", help="write the CSV only")
    p.add_argument("--json", action="store_true", help="print a JSON summary line")
    p.set_defaults(func=cmd_sweep)


def _seeds(text: str) -> list[int]:
    try:
        if "," in text:
            return [int(v) for v in text.split(",") if v.strip()]
        if "-" in text.strip()[1:]:
            a, b = text.split("-", 1)
            return list(range(int(a), int(b) + 1))
        n = int(text)
    except ValueError:
        raise UsageError(f"--seeds {text!r}: expected a count, A-B or a comma list") from None
    if n < 1:
        raise UsageError(f"--seeds {text!r}: expected at least 1")
    return list(range(1, n + 1))


def _grid(items: list[str]) -> dict:
    from bridge.commands.run import parse_value
    grid: dict = {}
    for item in items:
        key, eq, values = item.partition("=")
        if not eq or not values.strip():
            raise UsageError(f"--grid {item!r}: expected KEY=V1,V2,..., "
                             "e.g. --grid fieldDefiance=0,2,4")
        grid[key.strip()] = [parse_value(v.strip()) for v in values.split(",") if v.strip()]
    return grid


def cmd_sweep(args: argparse.Namespace) -> int:
    from bridge.commands.run import parse_overrides
    from sim_backend import scenario, sweep

    base = scenario.load(args.scenario)
    overrides = parse_overrides(args.set)
    if args.thesis:
        if args.grid:
            raise UsageError("--thesis runs its own grid; drop --grid")
        points = sweep.thesis_points()
        seeds = _seeds(args.seeds) if args.seeds else list(range(1, sweep.THESIS_SEEDS + 1))
        until = args.until or sweep.THESIS_UNTIL
        overrides.setdefault("maxTicks", sweep.THESIS_MAX_TICKS)
    else:
        if not args.grid:
            raise UsageError("give at least one --grid KEY=V1,V2,... (or --thesis)")
        points = sweep.grid_points(_grid(args.grid))
        seeds = _seeds(args.seeds) if args.seeds else list(range(1, 21))
        until = args.until or "delivered"
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
        if args.thesis:
            pngs = plots.thesis_plots(rows, args.out)
        else:
            pngs = plots.grid_plots(rows, list(_grid(args.grid)), args.out)
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
