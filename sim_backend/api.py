"""The Python API for notebooks (`import touchswarm`; docs/python-api.md).

run(scenario, seed, **overrides) -> Result   one run in the reference engine,
                                             with its summary, per-tick frame
                                             and final world
sweep(grid, seeds, ...) -> DataFrame         a grid x seeds, one row per run
                                             (the columns of sweep.csv)

Frames are pandas DataFrames when pandas is installed (`pip install
touchswarm[notebook]`), else lists of dicts with the same keys. Bad input
raises the project's typed errors (sim_backend.errors.ScenarioError, a
ValueError) before any run starts.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping

from sim_backend.errors import ScenarioError


def _frame(rows: list[dict]) -> Any:
    """A pandas DataFrame of rows when pandas is installed, else the rows."""
    try:
        import pandas as pd
    except ImportError:
        return rows
    return pd.DataFrame(rows)


@dataclass
class Result:
    """One run: what `touchswarm run` reports, as Python objects.

    summary   the run's summary (summary.json, docs/outputs.md)
    ticks     one row per tick (the --trace columns, docs/outputs.md)
    world     the simulated world at the end (sim_backend.world.World)
    scenario  the Scenario that ran; seed its seed
    """
    summary: dict
    ticks: Any
    world: Any
    scenario: Any
    seed: int

    def __repr__(self) -> str:
        s = self.summary
        return (f"Result(scenario={s['scenario']!r}, seed={self.seed}, ticks={s['ticks']}, "
                f"delivered={s['delivered']})")


def scenario_of(scenario: str | Path | Mapping[str, Any] = "default",
                overrides: Mapping[str, Any] | None = None):
    """A Scenario from a built-in name, a TOML path or a dict of keys (the
    rest default), with overrides applied; ScenarioError naming a bad key."""
    from sim_backend import scenario as scn
    if isinstance(scenario, Mapping):
        sc = scn.validate(dict(scenario), "scenario dict")
    elif isinstance(scenario, (str, Path)):
        sc = scn.load(scenario)
    else:
        raise ScenarioError(f"scenario: expected a built-in name, a .toml path or a dict, "
                            f"got {type(scenario).__name__}")
    if overrides:
        # merge: overrides naming another behaviour leave the old one's parameters behind
        sc = scn.validate(scn.merge(sc.to_dict(), dict(overrides)), "overrides")
    return sc


def run(scenario: str | Path | Mapping[str, Any] = "default", seed: int = 0,
        **overrides: Any) -> Result:
    """Run one scenario to the end in the reference engine.

    scenario: a built-in name (`touchswarm scenarios`), a .toml path or a
    dict of scenario keys; overrides: scenario keys, e.g. sigRadius=8.
    """
    from sim_backend.engine import Engine
    from sim_backend.scenario import check_seed
    from sim_backend.trace import Trace
    check_seed(seed, "seed")
    sc = scenario_of(scenario, overrides)
    engine = Engine(sc, seed)
    from perception.tracker import attach
    attach(engine)          # the shape estimate and verdict, as `touchswarm run` has them
    trace = Trace(engine)
    result = engine.run()
    ticks = [dict(zip(trace.names, row)) for row in trace.rows]
    return Result(summary=result.summary(), ticks=_frame(ticks), world=result.world,
                  scenario=sc, seed=seed)


def sweep(grid: Mapping[str, Iterable[Any]], seeds: int | Iterable[int] = 20,
          scenario: str | Path | Mapping[str, Any] = "default", engine: str = "auto",
          until: str = "delivered", executor: Any = None,
          progress: bool | Callable[[str], None] = True, **overrides: Any) -> Any:
    """Every grid point with every seed; one row per run in point, seed order.

    grid: {scenario key: [values]}, their product is the set of points.
    seeds: a count N (seeds 1..N) or the seeds themselves.
    engine: auto, soa or reference (sim_backend.sweep.ENGINES). auto does
      not wait for the soa engine's first compile: the runs start in the
      reference engine while it compiles in the background (the `engine`
      column says which engine ran each row); soa waits for it.
    executor: a concurrent.futures.Executor (None: this process).
    progress: True (default) prints progress lines on stderr (the first
      run, then every 5% of the runs or 10 s, and what the engine is doing:
      a background compile's start and end); a callable gets those lines
      instead; False prints nothing. The `sim_backend.sweep` logger hears
      the engine's news either way.
    overrides: scenario keys for every point, e.g. maxTicks=3000.
    """
    from sim_backend import sweep as sw
    if engine not in sw.ENGINES:
        raise ScenarioError(f"engine: expected one of {', '.join(sw.ENGINES)}, got {engine!r}")
    if until not in ("delivered", "converged"):
        raise ScenarioError(f"until: expected delivered or converged, got {until!r}")
    if isinstance(seeds, bool):
        raise ScenarioError(f"seeds: expected a count or a list of seeds, got {seeds!r}")
    seed_list = list(range(1, seeds + 1)) if isinstance(seeds, int) else list(seeds)
    if not isinstance(grid, Mapping):
        raise ScenarioError(f"grid: expected a dict {{key: [values]}}, got "
                            f"{type(grid).__name__}")
    grid_lists = {}
    for key, values in grid.items():
        if isinstance(values, (str, bytes)) or not isinstance(values, Iterable):
            raise ScenarioError(f"grid {key}: expected a list of values, got {values!r}")
        grid_lists[key] = list(values)
    base = scenario_of(scenario, overrides)
    points = sw.grid_points(grid_lists)
    emit: Callable[[str], None] | None
    if progress is True:
        import sys

        def emit(line: str) -> None:
            print(line, file=sys.stderr, flush=True)
    elif callable(progress):
        emit = progress
    elif progress is False or progress is None:
        emit = None
    else:
        raise ScenarioError(f"progress: expected True, False or a function of one line, "
                            f"got {progress!r}")
    step = on_event = None
    if emit is not None:
        status = sw.EngineStatus()
        step = sw.ProgressLog(len(points) * len(seed_list), emit, note=status.note).update

        def on_event(kind: str, text: str) -> None:
            status(kind, text)
            emit(f"sweep: {text}")
    rows = sw.sweep(points, seed_list, base=base, engine=engine, executor=executor,
                    until=until, progress=step, on_event=on_event)
    return _frame(rows)
