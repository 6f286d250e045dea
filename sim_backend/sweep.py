"""Parameter sweeps (the thesis's BehaviourSpace): points x seeds, in batches.

A point is a dict of scenario overrides; every point runs every seed. Runs
are cut into chunks; each chunk is one call of `run_chunk`, which steps its
runs together in the vectorised engine (or one by one in the reference
engine), so any concurrent.futures executor can spread the chunks: local
processes, a dask.distributed cluster (`executor_from_spec("dask://HOST:PORT")`)
or none (in this process). Rows come back in point, seed order whatever the
executor, so the CSV is the same everywhere.
"""

from __future__ import annotations

import csv
import itertools
import logging
import os
import socket
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

from sim_backend.errors import ScenarioError
from sim_backend.scenario import (FIELDS, Scenario, arena_features, check_seed, departures,
                                   validate)

log = logging.getLogger(__name__)
# how long to wait for a dask scheduler to answer before calling it unreachable
CONNECT_TIMEOUT_S = 5.0

# auto: the hand-vectorised thesis engine for the thesis behaviour (faster at
# sweep sizes, docs/performance.md), the compiled batch engine for any other
ENGINES = ("auto", "batch", "vector", "reference")
MEASURES = ["ticks", "found_tick", "converged_tick", "home_tick", "n_touches", "power",
            "shape_iou", "leader", "delivered", "segments"]
# the drawn pieces (tables, not values) go in one text column, `pieces`
PIECE_KEYS = ("objects", "obstacles")
SCENARIO_KEYS = [k for k in Scenario.__dataclass_fields__
                 if k not in ("name", "description") + PIECE_KEYS]


@dataclass(frozen=True)
class Point:
    """One grid point: an experiment label and scenario overrides."""
    experiment: str
    params: tuple[tuple[str, Any], ...]

    def as_dict(self) -> dict[str, Any]:
        return dict(self.params)


def grid_points(grid: dict[str, Sequence[Any]], experiment: str = "grid") -> list[Point]:
    """The cartesian product of a grid {key: [values]}, in the grid's key order."""
    for key, values in grid.items():
        if key not in FIELDS:
            raise ScenarioError(f"--grid {key}: unknown scenario key; known keys: "
                                f"{', '.join(sorted(FIELDS))}")
        if not values:
            raise ScenarioError(f"--grid {key}: no values; expected {key}=V1,V2,...")
        seen: list[Any] = []
        for v in values:
            # a repeated value would run (and average) the same point twice
            if v in seen:
                raise ScenarioError(f"--grid {key}: value {v!r} is listed twice; "
                                    "give each value once")
            seen.append(v)
    keys = list(grid)
    return [Point(experiment, tuple(zip(keys, combo)))
            for combo in itertools.product(*(grid[k] for k in keys))]


def thesis_points() -> list[Point]:
    """Every experiment of the thesis's chapter 5, both movement models.

    graph1 fieldDefiance, graph2 sigRadius, graph3 rPower (graph 4, robots
    required = ceil(objectWeight / rPower) of a population of 20, is the same
    data read the other way, as the thesis says); figures 22-24: the shape N
    touching robots extract (objectWeight = N, rPower 1) from a swarm of
    max(20, N), for the bar, L, '+' (cross, DrawObject 3) and X objects.
    """
    pts: list[Point] = []
    models = ("firefly", "ant")
    for m in models:
        for v in (0, 1, 2, 4, 6, 8, 10):
            pts.append(Point("graph1", (("movementModel", m), ("fieldDefiance", v))))
    for m in models:
        for v in (1, 2, 3, 5, 7, 9):
            pts.append(Point("graph2", (("movementModel", m), ("sigRadius", v))))
    for m in models:
        for v in (0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 5.0):
            pts.append(Point("graph3", (("movementModel", m), ("rPower", v))))
    for obj in ("bar", "L", "cross", "X"):
        for n in (4, 6, 8, 10, 12):
            pts.append(Point("shapes", (("object", obj), ("agents", max(20, n)),
                                        ("objectWeight", float(n)))))
    return pts


THESIS_SEEDS = 150
THESIS_MAX_TICKS = 5000
THESIS_UNTIL = "converged"


def _scenario(base: dict[str, Any], params: dict[str, Any]) -> Scenario:
    return validate({**base, **params}, "sweep point " + ", ".join(
        f"{k}={v}" for k, v in params.items()))


def pick_engine(engine: str, sc: Scenario) -> str:
    """The engine `auto` stands for, for runs of `sc`: the hand-vectorised
    engine for the thesis behaviour with the default rules only."""
    if engine != "auto":
        return engine
    return "vector" if sc.behaviour == "thesis" and not departures(sc) \
        and not arena_features(sc) else "batch"


def run_chunk(jobs: Sequence[tuple[dict, dict, int]], engine: str = "auto",
              until: str = "delivered") -> list[dict]:
    """Run (base scenario dict, point params, seed) jobs; return one summary each.

    A plain top-level function, so every executor can ship it.
    """
    scs = [_scenario(b, p) for b, p, _ in jobs]
    seeds = [s for _, _, s in jobs]
    if engine == "auto":
        out: list[dict | None] = [None] * len(jobs)
        groups: dict[str, list[int]] = {}
        for j, sc in enumerate(scs):
            groups.setdefault(pick_engine(engine, sc), []).append(j)
        for eng, idx in groups.items():
            for j, summ in zip(idx, run_chunk([jobs[j] for j in idx], eng, until)):
                out[j] = summ
        return out  # type: ignore[return-value]
    if engine == "vector":
        from sim_backend.vector_engine import run_batch
        return run_batch(scs, seeds, until=until)
    if engine == "batch":
        from sim_backend.batch.engine import run_batch as run_compiled
        return run_compiled(scs, seeds, until=until)
    if engine != "reference":
        raise ValueError(f"engine: expected one of {ENGINES}, got {engine!r}")
    from sim_backend.engine import Engine, RunResult
    out = []
    for sc, seed in zip(scs, seeds):
        e = Engine(sc, seed)
        if until == "delivered":
            out.append(e.run().summary())
            continue
        while not (e.coordinator.converged_tick >= 0 or e.tick >= sc.maxTicks):
            e.step()
        out.append(RunResult(sc, seed, e.tick, e.world, e.coordinator, e.robots).summary())
    return out


def check_seeds(seeds: Sequence[int]) -> None:
    """ScenarioError unless seeds is a non-empty list of distinct valid seeds."""
    if not seeds:
        raise ScenarioError("seeds: none given; expected at least one seed")
    seen: set[int] = set()
    for s in seeds:
        check_seed(s, "seed")
        if s in seen:
            # a repeated seed is the same run again: it would inflate the sample
            raise ScenarioError(f"seed {s} is listed twice; give each seed once")
        seen.add(s)


def _dask_address(spec: str) -> tuple[str, str, int]:
    """("tcp://HOST:PORT", HOST, PORT) of a dask://HOST:PORT spec."""
    hostport = spec.split("://", 1)[1].rstrip("/")
    host, colon, port = hostport.rpartition(":")
    if not colon or not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"executor {spec!r}: expected dask://HOST:PORT with a port "
                         "1..65535, e.g. dask://127.0.0.1:8786")
    return f"tcp://{host}:{port}", host.strip("[]"), int(port)


def executor_from_spec(spec: str | None):
    """(executor, closer) for "processes[:N]", "inline" or "dask://HOST:PORT".

    A dask scheduler is reached within CONNECT_TIMEOUT_S or refused with a
    ValueError naming the address, before any run is submitted."""
    if spec is None or spec == "processes" or spec.startswith("processes:"):
        n = os.cpu_count() or 1
        if spec and ":" in spec:
            text = spec.split(":", 1)[1]
            if not text.isdigit() or int(text) < 1:
                raise ValueError(f"executor {spec!r}: expected processes:N with N >= 1 "
                                 "worker processes")
            n = int(text)
        ex = ProcessPoolExecutor(max_workers=n)
        return ex, ex.shutdown
    if spec == "inline":
        return None, (lambda: None)
    if spec.startswith("dask://") or spec.startswith("tcp://"):
        address, host, port = _dask_address(spec)
        # dask's own connect retries for 30 s and then raises from deep inside;
        # a plain TCP connect tells a wrong address at once
        try:
            with socket.create_connection((host, port), timeout=CONNECT_TIMEOUT_S):
                pass
        except OSError as err:
            raise ValueError(f"executor {spec}: no dask scheduler reachable at {host}:{port} "
                             f"({err.strerror or err}); start one with `dask scheduler` or "
                             "use --executor processes") from None
        from distributed import Client
        try:
            client = Client(address, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError) as err:
            raise ValueError(f"executor {spec}: {host}:{port} answers but is not a dask "
                             f"scheduler ({err})") from None
        log.info("connected to dask scheduler %s", address)
        return client.get_executor(), client.close
    raise ValueError(f"executor: expected processes[:N], inline or dask://HOST:PORT, got {spec!r}")


def validate_points(points: Sequence[Point], base: Scenario | None = None,
                    overrides: dict[str, Any] | None = None) -> None:
    """ScenarioError for the first point that is not a valid scenario."""
    if not points:
        raise ScenarioError("sweep: no grid points; expected at least one")
    base_d = (base or Scenario()).to_dict()
    base_d.update(overrides or {})
    for pt in points:
        _scenario(base_d, pt.as_dict())


def sweep(points: Sequence[Point], seeds: Iterable[int], base: Scenario | None = None,
          engine: str = "auto", executor: Executor | None = None, until: str = "delivered",
          chunk_size: int = 256, overrides: dict[str, Any] | None = None,
          progress: Callable[[int], None] | None = None) -> list[dict]:
    """Run every point with every seed; return tidy rows in point, seed order.

    executor: any concurrent.futures.Executor (None: run in this process).
    overrides: scenario keys applied to every point (e.g. maxTicks).
    progress: called with the number of runs just finished.
    """
    if engine not in ENGINES:
        raise ValueError(f"engine: expected one of {ENGINES}, got {engine!r}")
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1:
        raise ValueError(f"chunk_size: expected at least 1 run per chunk, got {chunk_size!r}")
    seeds = list(seeds)
    check_seeds(seeds)
    if not points:
        raise ScenarioError("sweep: no grid points; expected at least one")
    base_d = (base or Scenario()).to_dict()
    base_d.update(overrides or {})
    jobs: list[tuple[dict, dict, int]] = []
    meta: list[tuple[Point, Scenario, int]] = []
    for pt in points:
        sc = _scenario(base_d, pt.as_dict())        # validate every point up front
        for s in seeds:
            jobs.append((base_d, pt.as_dict(), s))
            meta.append((pt, sc, s))
    chunks = [jobs[i:i + chunk_size] for i in range(0, len(jobs), chunk_size)]
    results: list[list[dict] | None] = [None] * len(chunks)
    if executor is None:
        for i, ch in enumerate(chunks):
            results[i] = run_chunk(ch, engine, until)
            if progress is not None:
                progress(len(ch))
    else:
        futs: dict[Future, int] = {executor.submit(run_chunk, ch, engine, until): i
                                   for i, ch in enumerate(chunks)}
        for f in as_completed(futs):
            i = futs[f]
            results[i] = f.result()
            if progress is not None:
                progress(len(chunks[i]))
    sums = [s for r in results for s in r]  # type: ignore[union-attr]
    return [make_row(pt, sc, s, summ, until) for (pt, sc, s), summ in zip(meta, sums)]


def make_row(pt: Point, sc: Scenario, seed: int, s: dict, until: str) -> dict:
    row: dict[str, Any] = {"experiment": pt.experiment,
                           "point": ";".join(f"{k}={v}" for k, v in pt.params)}
    for k in SCENARIO_KEYS:
        row[k] = getattr(sc, k)
    row["pieces"] = " ".join(repr(p) for k in PIECE_KEYS for p in getattr(sc, k))
    row["required"] = -(-sc.weight_centi // sc.power_centi)
    row["seed"] = seed
    row["until"] = until
    row["ticks"] = s["ticks"]
    row["found_tick"] = s["found_tick"]
    row["converged_tick"] = s["converged_tick"]
    row["home_tick"] = s["home_tick"]
    row["n_touches"] = len(s["touches"])
    row["power"] = s["power"]
    row["shape_iou"] = s["shape_iou"]
    row["leader"] = s["leader"]
    row["delivered"] = s["delivered"]
    row["segments"] = " ".join(f"{x}:{y}" for x, y in s["segments"])
    # the measures the behaviour declares (spec.MEASURES) that the columns
    # above do not already hold, e.g. aggregation's stopped/clusters/largest
    from firmware_logic import registry
    for name, _ in registry.load(sc.behaviour).spec.MEASURES:
        if name not in row:
            row[name] = s.get(name)
    return row


def write_csv(rows: Sequence[dict], path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as f:
        if not rows:
            return path
        # rows of different behaviours carry different measures: every column once
        names = list(dict.fromkeys(k for r in rows for k in r))
        wr = csv.DictWriter(f, fieldnames=names, lineterminator="\n")
        wr.writeheader()
        for r in rows:
            wr.writerow({k: ("" if v is None else v) for k, v in r.items()})
    return path


def read_csv(path: Path) -> list[dict]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


