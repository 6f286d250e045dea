"""`touchswarm sweep`: a grid of scenario parameters x seeds (BehaviourSpace)."""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bridge.commands.paths import path_arg
from bridge.errors import UsageError
from sim_backend.sweep import ENGINES, SMALL_SWEEP_ROBOTS, SOA_COLD_COMPILE


def register(sub) -> None:
    p = sub.add_parser(
        "sweep",
        description="Run every grid point with every seed (the thesis's BehaviourSpace) in the "
                    "vectorised engine, spread over an executor; write one CSV row per run "
                    "(every parameter and every measured figure) and PNG plots.",
        epilog="examples:\n"
               "  touchswarm sweep --grid agents=10,20,40 --grid sigRadius=3,5 --seeds 150\n"
               "  touchswarm sweep --study thesis --out thesis-out   # a study of the behaviour\n"
               "  touchswarm sweep --grid sigRadius=3,5,7 --seeds 101-200 --executor "
               "dask://10.0.0.5:8786\n"
               "  touchswarm sweep --grid sigRadius=3,5 --save-experiment exp.toml  # saved, run\n"
               "  touchswarm sweep exp.toml --resume           # finish an interrupted sweep\n"
               "\nEverything is checked before the first run: keys and values, seeds (distinct, "
               "0..1000002),\nthe output directory and the executor. Exit 0 when every run "
               "finished, 2 on bad input.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("experiment", nargs="?", type=path_arg, metavar="EXPERIMENT.toml",
                   help="an experiment file (scenario, grid, set, seeds, engine, until, out, "
                        "executor, chunk; docs/outputs.md); options given as well override "
                        "its values")
    p.add_argument("--scenario", default=None, metavar="NAME|FILE",
                   help="base scenario every point starts from (default: default)")
    p.add_argument("--grid", action="append", default=[], metavar="KEY=V1,V2,...",
                   help="a scenario key and its distinct values (repeatable, once per key; "
                        "the grid is their product; none: one point, the scenario with "
                        "its --set keys)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key for every point (repeatable, once per key, "
                        "not a --grid key)")
    p.add_argument("--seeds", default=None, metavar="N|A-B|A,B,...",
                   help="seeds: a count N (seeds 1..N), a range A-B (A <= B) or a list of "
                        "distinct seeds, each in 0..1000002 (default: 20; a study: its own)")
    p.add_argument("--study", default=None, metavar="NAME",
                   help="run a study of the scenario's behaviour: its own points, seeds, "
                        "until, settings and figures, declared as data in the behaviour's "
                        "studies.py (`touchswarm scenarios --behaviour NAME` lists them; "
                        "docs/writing-a-behaviour.md, \"Studies\"); --seeds, --until and "
                        "--set given as well override the study's")
    p.add_argument("--preset", default=None, metavar="NAME",
                   help="sizes: 20-300 robots in the default arena, 1,000 and 10,000 in "
                        "arenas of the same density; obstacles: the wall scenario with and "
                        "without its wall; field: static and dynamic field at 20-300 robots "
                        "(the world's presets; 10 seeds, until delivered, maxTicks "
                        "6000; <preset>.png: delivery rate, time, IoU). Any other NAME is "
                        "--study NAME (the thesis's faults: each fault alone and a mix, "
                        "faults.png; breeds: the share of ants, breeds.png)")
    p.add_argument("--thesis", action="store_true",
                   help="the same as --study thesis: every graph and figure of the thesis's "
                        "chapter 5 (150 seeds per point, both movement models, until "
                        "convergence)")
    p.add_argument("--activation", choices=["sync", "netlogo"], default=None,
                   help="sync: every robot decides on the tick-start world (the scenario's "
                        "default); netlogo: NetLogo's sequential `ask robots` "
                        "(docs/tick-semantics.md); the same as --set activation=...")
    p.add_argument("--until", choices=["delivered", "converged"], default=None,
                   help="stop each run when the object is home or when power first reaches "
                        "its weight (default: delivered; a study: its own)")
    p.add_argument("--engine", choices=ENGINES, default=None,
                   help="soa: the struct-of-arrays transform of the behaviour's own "
                        "source, compiled once per machine and behaviour source "
                        f"({SOA_COLD_COMPILE}, said on stderr; TOUCHSWARM_SOA_INLINE=0 halves "
                        "it, for slower runs) and cached on disk (~/.cache/touchswarm or "
                        "$TOUCHSWARM_CACHE); soa waits for that compile before the first run. "
                        "auto (default): soa when the cache holds it; when not, the runs start "
                        "at once in the reference engine while the soa engine compiles in a "
                        "background process, and the runs not started when it is done go to "
                        "soa (sweep.csv's engine column says which engine ran each row; a "
                        "failed compile leaves the sweep in the reference engine, said in one "
                        "line; a compile still going when the sweep ends goes on and fills "
                        "the cache). reference: the per-robot engine, bit-identical and over "
                        "100x slower at 10,000 robots (docs/performance.md)")
    p.add_argument("--executor", default=None, metavar="SPEC",
                   help="processes[:N] (default: one per core; a sweep of at most "
                        f"{SMALL_SWEEP_ROBOTS:,} robots in all in the soa engine runs in this "
                        "process unless --chunk is given), inline, or dask://HOST:PORT (a "
                        "dask.distributed scheduler)")
    p.add_argument("--chunk", type=int, default=None, metavar="RUNS",
                   help="runs per task, at least 1 (default: one task per worker, at most 256 runs)")
    p.add_argument("--out", type=path_arg, default=None, metavar="DIR",
                   help="directory (created if missing) for sweep.csv and the PNGs "
                        "(default: sweep-out)")
    p.add_argument("--resume", action="store_true",
                   help="finish the sweep whose sweep.csv is in --out: runs already there "
                        "(same experiment, point and seed) are kept, not run again")
    p.add_argument("--overwrite", action="store_true",
                   help="replace a sweep.csv already in --out (without it, a sweep refuses "
                        "to throw away finished runs)")
    p.add_argument("--save-experiment", type=path_arg, metavar="FILE.toml",
                   help="save this sweep's settings as an experiment file, then run it; "
                        "`touchswarm sweep FILE.toml` runs it again")
    p.add_argument("--progress-every", type=float, default=10.0, metavar="S",
                   help="when stderr is not a terminal: a progress line at least every S "
                        "seconds (and every 5%% of the runs) (default: %(default)s)")
    p.add_argument("--no-plots", action="store_true", help="write the CSV only")
    p.add_argument("--json", action="store_true", help="print a JSON summary line")
    from bridge.commands.run import add_trust_arg
    add_trust_arg(p)
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
            if a < SEED_MIN or b > SEED_MAX:
                # before the list is built: 1-99999999999999 must not exhaust memory
                bad = a if a < SEED_MIN else SEED_MAX + 1
                raise UsageError(f"--seeds {text}: seed {bad} is outside {SEED_MIN}..{SEED_MAX} "
                                 f"(the firmware RNG takes seeds modulo 1000003; at most "
                                 f"{SEED_MAX - SEED_MIN + 1:,} seeds)")
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
                             "e.g. --grid agents=10,20")
        if key in grid:
            raise UsageError(f"--grid {key} given twice; put all its values in one "
                             f"--grid {key}=V1,V2,...")
        grid[key] = [parse_value(v.strip()) for v in values.split(",") if v.strip()]
    return grid


def _settings(args: argparse.Namespace) -> dict:
    """The sweep's settings: the experiment file's, overridden by options given."""
    from bridge.commands import experiment
    from bridge.commands.run import parse_overrides
    settings: dict = {}
    if args.experiment is not None:
        if args.experiment.suffix != ".toml":
            raise UsageError(f"experiment {args.experiment}: expected a .toml experiment file")
        if _study_flag(args):
            raise UsageError(f"{_study_flag(args)} runs its own grid; drop the experiment file")
        settings = experiment.load(args.experiment)
    if args.scenario is not None:
        settings["scenario"] = args.scenario
    if args.grid:
        settings["grid"] = _grid(args.grid)
    elif "grid" in settings:
        grid = settings["grid"]
        settings["grid"] = {k: list(v) for k, v in grid.items()}
    if args.set:
        settings["set"] = parse_overrides(args.set)
    if args.seeds is not None:
        settings["seeds"] = args.seeds
    elif "seeds" in settings:
        settings["seeds"] = experiment.seeds_text(settings["seeds"])
    for key in ("engine", "until", "out", "executor", "chunk"):
        if getattr(args, key) is not None:
            settings[key] = getattr(args, key)
    if "engine" in settings and settings["engine"] not in ENGINES:
        raise UsageError(f"engine {settings['engine']!r}: expected one of {', '.join(ENGINES)}")
    if "until" in settings and settings["until"] not in ("delivered", "converged"):
        raise UsageError(f"until {settings['until']!r}: expected delivered or converged")
    settings.setdefault("scenario", "default")
    settings.setdefault("set", {})
    settings.setdefault("engine", "auto")
    settings.setdefault("executor", "processes")
    settings["out"] = Path(settings.get("out") or "sweep-out")
    return settings


def _world_presets() -> tuple[str, ...]:
    from sim_backend import arena_presets
    return tuple(arena_presets.PRESETS)


def _study_flag(args: argparse.Namespace) -> str | None:
    """The option that names a study or a preset, as given (for errors)."""
    if args.study:
        return f"--study {args.study}"
    if args.preset:
        return f"--preset {args.preset}"
    return "--thesis" if args.thesis else None


def _compiling(behaviour: str, folder: Path) -> None:
    print(f"compiling the soa engine for behaviour {behaviour!r}: once per machine and "
          f"behaviour source, {SOA_COLD_COMPILE}; cached in {folder}", file=sys.stderr,
          flush=True)


@dataclass
class Plan:
    """What one sweep runs: its base scenario and overrides, its points and
    seeds, until when, and the study or grid it came from (for its figures)."""
    base: Any
    overrides: dict
    points: list
    seeds: list[int]
    until: str
    study: Any = None
    grid: dict = field(default_factory=dict)


def cmd_sweep(args: argparse.Namespace) -> int:
    from bridge.commands.run import trust_from_args
    trust_from_args(args)
    cfg = _settings(args)
    plan = _plan(args, cfg)
    chunk = cfg.get("chunk")      # None: the sweep sizes them (sweep.chunk_runs)
    if chunk is not None and chunk < 1:
        raise UsageError(f"--chunk {chunk}: expected at least 1 run per task")
    out: Path = cfg["out"]
    # every check that can refuse the sweep runs before the first run
    done = _check_out(args, plan, out)
    if args.save_experiment is not None:
        _save_experiment(args, cfg, plan, out)
    names = _columns(plan)
    new, wall, journal = _run(args, cfg, plan, out, done, names)
    rows = _in_run_order(plan, done + new)
    from sim_backend import sweep
    csv_path = out / "sweep.csv"
    # the rows came back out of run order: the journal's chunks put in order,
    # or (a resumed sweep's) every row written again
    if not journal.holds(rows) and not journal.reorder(rows):
        sweep.write_csv(rows, csv_path, names)
    pngs = [] if args.no_plots else _draw(args, plan, csv_path, out)
    _report(args, cfg, plan, rows, new, done, wall, csv_path, pngs)
    # every file is written and closed (sweep.csv, the figures): the process
    # need not free the soa step's numba objects one by one at its exit
    from bridge.cli import skip_teardown
    skip_teardown()
    return 0


def _plan(args: argparse.Namespace, cfg: dict) -> Plan:
    """The points and seeds the options name: a world preset, a behaviour's
    study (or --thesis), else the --grid (one point without one)."""
    from sim_backend import scenario
    base = scenario.load(cfg["scenario"])
    overrides = dict(cfg["set"])
    if args.activation is not None:
        if "activation" in overrides or "activation" in cfg.get("grid", {}):
            raise UsageError("--activation and --set/--grid activation both given; give one")
        overrides["activation"] = args.activation
        cfg["set"] = dict(cfg["set"], activation=args.activation)   # saved with the experiment
    flag = _study_flag(args)
    if sum(map(bool, (args.preset, args.study, args.thesis))) > 1:
        raise UsageError("--preset, --study and --thesis each run their own grid; give one")
    if flag and cfg.get("grid"):
        raise UsageError(f"{flag} runs its own grid; drop --grid")
    if flag and args.save_experiment:
        raise UsageError(f"--save-experiment saves a --grid sweep; {flag} is its own "
                         "experiment already")
    # a sweep without --preset never imports the presets (and the plotting
    # modules they import)
    if args.preset and args.preset in _world_presets():
        return _preset_plan(args, cfg, base, overrides)
    if flag:
        return _study_plan(args, cfg, base, overrides)
    return _grid_plan(cfg, base, overrides)


def _preset_plan(args: argparse.Namespace, cfg: dict, base: Any, overrides: dict) -> Plan:
    from sim_backend import arena_presets, scenario
    name, make = arena_presets.PRESETS[args.preset]
    if args.scenario is None and args.experiment is None:
        base = scenario.load(name)
    seeds = _seeds(cfg["seeds"]) if "seeds" in cfg else list(range(1, arena_presets.SEEDS + 1))
    overrides.setdefault("maxTicks", arena_presets.MAX_TICKS)
    plan = Plan(base, overrides, make(), seeds, cfg.get("until") or "delivered")
    _validate(plan)
    return plan


def _study_plan(args: argparse.Namespace, cfg: dict, base: Any, overrides: dict) -> Plan:
    from sim_backend import studies, sweep
    behaviour = str(sweep.base_dict(base, overrides)["behaviour"])
    try:
        study = studies.get(behaviour, args.study or args.preset or "thesis")
    except studies.StudyError as err:
        if args.preset:      # neither the world's preset nor the behaviour's study
            raise UsageError(f"--preset {args.preset}: not a world preset "
                             f"({', '.join(_world_presets())}); {err}") from None
        raise
    seeds = _seeds(cfg["seeds"]) if "seeds" in cfg else list(range(1, study.seeds + 1))
    for key, value in study.overrides:
        overrides.setdefault(key, value)
    studies.check(study, base, overrides)     # errors name the study
    return Plan(base, overrides, list(study.points), seeds, cfg.get("until") or study.until,
                study=study)


def _grid_plan(cfg: dict, base: Any, overrides: dict) -> Plan:
    """--grid's points (no --grid: one point, the scenario with --set)."""
    from sim_backend import sweep
    grid = cfg.get("grid") or {}
    both = sorted(set(grid) & set(overrides))
    if both:
        raise UsageError(f"--set {both[0]} and --grid {both[0]} both given; the grid "
                         "would override --set: give the key in one of them")
    seeds = _seeds(cfg["seeds"]) if "seeds" in cfg else list(range(1, 21))
    plan = Plan(base, overrides, sweep.grid_points(grid), seeds,
                cfg.get("until") or "delivered", grid=grid)
    _validate(plan)
    return plan


def _validate(plan: Plan) -> None:
    from sim_backend import sweep
    sweep.validate_points(plan.points, plan.base, plan.overrides)


def _columns(plan: Plan) -> list[str]:
    from sim_backend import sweep
    return sweep.columns(sweep.point_behaviours(plan.points, plan.base, plan.overrides))


def _check_out(args: argparse.Namespace, plan: Plan, out: Path) -> list[dict]:
    """The runs --resume keeps from out/sweep.csv (none without it); a
    UsageError when out/ holds a sweep that neither --resume nor
    --overwrite was given for."""
    from sim_backend import sweep

    from bridge.commands.paths import check_out_dir
    check_out_dir(out, "--out")
    csv_path = out / "sweep.csv"
    if args.resume:
        done = sweep.read_done(csv_path)
        sweep.check_done(done, plan.points, plan.seeds,
                         sweep.base_dict(plan.base, plan.overrides), plan.until)
        return done
    if csv_path.exists() and not args.overwrite and sweep.read_done(csv_path):
        raise UsageError(f"--out {out}: sweep.csv already holds {len(sweep.read_done(csv_path))}"
                         " runs; --resume finishes that sweep, --overwrite replaces it")
    return []


def _save_experiment(args: argparse.Namespace, cfg: dict, plan: Plan, out: Path) -> None:
    from bridge.commands import experiment
    from bridge.commands.paths import check_out_file
    check_out_file(args.save_experiment, "--save-experiment", "exp.toml")
    if args.save_experiment.suffix != ".toml":
        raise UsageError(f"--save-experiment {args.save_experiment}: expected a .toml file")
    experiment.save(args.save_experiment, {
        "scenario": cfg["scenario"], "grid": plan.grid, "set": cfg["set"],
        "seeds": _seeds_value(cfg.get("seeds", "20")), "engine": cfg["engine"],
        "until": plan.until, "out": str(out), "executor": cfg["executor"],
        "chunk": cfg.get("chunk")})
    print(f"experiment saved to {args.save_experiment}")


def _run(args: argparse.Namespace, cfg: dict, plan: Plan, out: Path, done: list[dict],
         names: list[str]) -> tuple[list[dict], float, Any]:
    """Run what is not done yet, each row appended to out/sweep.csv (columns
    `names`) as it comes, with progress on stderr: (the new rows, wall
    seconds, the journal: sweep.CsvAppender)."""
    from sim_backend import sweep
    try:
        executor, close = sweep.executor_from_spec(cfg["executor"])
    except ValueError as err:
        raise UsageError(str(err)) from None
    csv_path = out / "sweep.csv"
    total = len(plan.points) * len(plan.seeds)
    appender = sweep.CsvAppender(csv_path, names, resume=args.resume)
    if done:
        print(f"resuming: {len(done)} of {total} runs already in {csv_path}", file=sys.stderr)
    # --engine soa: compile (or load) the engine first, so the progress rate
    # counts runs only; auto does not wait (a cold cache compiles in the
    # background while the runs start in the reference engine)
    if total > len(done) and cfg["engine"] == "soa":
        sweep.warm(sweep.point_scenarios(plan.points, plan.base, plan.overrides),
                   cfg["engine"], _compiling)
    status = sweep.EngineStatus()
    bar, step = _progress(total, len(done), args.progress_every, status.note)

    def on_event(kind: str, text: str) -> None:
        status(kind, text)
        line = f"sweep: {text}"
        if bar is not None:
            bar.set_postfix_str(status.note(), refresh=False)
            bar.write(line, file=sys.stderr)
        else:
            print(line, file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    try:
        new = sweep.sweep(plan.points, plan.seeds, base=plan.base, engine=cfg["engine"],
                          executor=executor, until=plan.until, chunk_size=cfg.get("chunk"),
                          overrides=plan.overrides, progress=step, on_rows=appender.append,
                          done=done, compile_first=cfg["engine"] != "soa", on_event=on_event)
    finally:
        appender.close()
        if bar is not None:
            bar.close()
        close()
    return new, time.perf_counter() - t0, appender


def _in_run_order(plan: Plan, rows: list[dict]) -> list[dict]:
    """The rows in point, seed order (the journal holds them in the order runs
    finished), so the same sweep gives the same file whatever the executor."""
    from sim_backend import sweep
    order = {run: i for i, run in enumerate(
        (pt.experiment, ";".join(f"{k}={v}" for k, v in pt.params), str(s))
        for pt in plan.points for s in plan.seeds)}
    return sorted(rows, key=lambda r: order[sweep.run_key(r)])


def _draw(args: argparse.Namespace, plan: Plan, csv_path: Path, out: Path) -> list[Path]:
    """The sweep's figures: its study's, its world preset's, or one per grid key."""
    from sim_backend import sweep
    saved = sweep.read_csv(csv_path)
    if plan.study is not None:
        from sim_backend import studies
        return studies.draw(plan.study, saved, out)
    if args.preset:
        from sim_backend import arena_presets
        return arena_presets.plots(saved, out, args.preset)
    from sim_backend import plots
    return plots.grid_plots(saved, list(plan.grid), out)


def _report(args: argparse.Namespace, cfg: dict, plan: Plan, rows: list[dict],
            new: list[dict], done: list[dict], wall: float, csv_path: Path,
            pngs: list[Path]) -> None:
    """What ran, printed as one JSON object (--json) or a few lines."""
    from sim_backend import sweep
    engines: dict[str, int] = {}
    for r in new:
        engines[r["engine"]] = engines.get(r["engine"], 0) + 1
    if args.json:
        print(json.dumps({
            "runs": len(rows), "new_runs": len(new), "resumed_runs": len(done),
            "points": len(plan.points), "seeds": len(plan.seeds), "engine": cfg["engine"],
            "engines": engines, "executor": cfg["executor"], "until": plan.until,
            "wall_s": round(wall, 3), "csv": str(csv_path), "plots": [str(p) for p in pngs]},
            sort_keys=True))
        return
    again = f", {len(done)} kept from before" if done else ""
    # the engines that ran the new runs: one, or "12 reference + 8 soa"
    used = " + ".join(f"{n} {e}" for e, n in engines.items()) if len(engines) > 1 else \
        next(iter(engines), sweep.pick_engine(cfg["engine"]))
    engine = used if used == cfg["engine"] else f"{used} ({cfg['engine']})"
    print(f"{len(rows)} runs ({len(plan.points)} points x {len(plan.seeds)} seeds, {engine} "
          f"engine, until {plan.until}{again}) in {wall:.1f} s")
    print(f"  {csv_path}")
    for p in pngs:
        print(f"  {p}")


def _seeds_value(text: str) -> int | str | list[int]:
    """--seeds text as an experiment file writes it: a count stays a number."""
    text = str(text).strip()
    return int(text) if text.isdigit() else text


def _progress(total: int, already: int, every_s: float, note):
    """(bar or None, step(n)): a tqdm bar on a terminal, else log lines on
    stderr; note() (what the engine is doing) ends the bar or each line."""
    if sys.stderr.isatty():
        from tqdm import tqdm
        bar = tqdm(total=total, initial=already, unit="run", desc="sweep")

        def step(n: int) -> None:
            bar.set_postfix_str(note(), refresh=False)
            bar.update(n)
        return bar, step
    from sim_backend.sweep import ProgressLog
    log = ProgressLog(total, lambda line: print(line, file=sys.stderr, flush=True),
                      already=already, every_s=every_s, note=note)
    return None, log.update
