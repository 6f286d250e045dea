"""Parameter sweeps (the thesis's BehaviourSpace): points x seeds, in batches.

A point is a dict of scenario overrides; every point runs every seed. Runs
are cut into chunks; each chunk is one call of `run_chunk`, which steps its
runs together in a batch engine compiled from the behaviour's source (or one
by one in the reference engine), so any concurrent.futures executor can
spread the chunks: local processes, a dask.distributed cluster
(`executor_from_spec("dask://HOST:PORT")`) or none (in this process). Rows
come back in point, seed order whatever the executor, so the CSV is the
same everywhere.
"""

from __future__ import annotations

import csv
import itertools
import logging
import os
import socket
import struct
import sys
from concurrent.futures import Executor, Future, ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any, Callable, Iterable, Iterator, Mapping, Sequence

from sim_backend import params
from sim_backend.errors import ScenarioError
from sim_backend.scenario import (DEFAULT_BEHAVIOUR, FIELDS, Scenario, check_seed, holders_needed,
                                  link_faults,
                                  merge, validate)

log = logging.getLogger(__name__)
# how long to wait for a dask scheduler to answer before calling it unreachable
CONNECT_TIMEOUT_S = 5.0

# auto: the struct-of-arrays engine (sim_backend/batch/soa.py), compiled and
# cached on disk (docs/performance.md); reference: one Engine per run
ENGINES = ("auto", "soa", "reference")
# how long the soa engine's first compile of a behaviour takes on a 2-core
# machine (docs/performance.md: aggregate 80-95 s, thesis 142-206 s)
SOA_COLD_COMPILE = "1.5-3.5 min"
# engine auto on a cold cache: the runs start in the reference engine while
# the soa step compiles in another process; reference chunks hold this many
# runs, so that the runs move to soa within a few runs of the compile's end
REFERENCE_CHUNK = 4
# what a sweep's on_event(kind, text) hears about a background compile
EVENTS = ("compiling", "compiled", "failed", "left")
# every behaviour's columns (the world's, the host contract's and the host
# perception's estimate, empty for a behaviour that perceives no object);
# then each behaviour's own declared measures (columns())
MEASURES = ["ticks", "n_touches", "delivered", "touches", "estimate_iou", "recognised", "p"]
# the drawn pieces (tables, not values) go in one text column, `pieces`
PIECE_KEYS = ("objects", "obstacles", "library")
# [[breeds]] tables go in one text column too, `breeds`; the world's keys,
# then each behaviour's own parameters (columns())
SCENARIO_KEYS = [k for k in Scenario.__dataclass_fields__
                 if k not in ("name", "description", "breeds", "params") + PIECE_KEYS]


def row_keys(row: dict[str, Any]) -> list[str]:
    """The scenario keys a sweep.csv row holds: the world's, then its
    behaviour's own parameters."""
    from sim_backend import params
    return [*SCENARIO_KEYS, *params.names(row.get("behaviour") or DEFAULT_BEHAVIOUR)]


@dataclass(frozen=True)
class Point:
    """One grid point: an experiment label and scenario overrides."""
    experiment: str
    params: tuple[tuple[str, Any], ...]

    def as_dict(self) -> dict[str, Any]:
        return dict(self.params)


def grid_points(grid: Mapping[str, Sequence[Any]], experiment: str = "grid") -> list[Point]:
    """The cartesian product of a grid {key: [values]}, in the grid's key order."""
    # a key is checked with the point's scenario (the behaviour's own
    # parameters are keys too): validate_points
    for key, values in grid.items():
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


def base_dict(base: Scenario | None, overrides: dict[str, Any] | None) -> dict[str, Any]:
    """The keys every point starts from: the base scenario's with the --set
    overrides over them (an override naming another behaviour leaves the base
    behaviour's own parameters behind: scenario.merge)."""
    return merge((base or Scenario()).to_dict(), dict(overrides or {}))


def _scenario(base: dict[str, Any], point: dict[str, Any]) -> Scenario:
    behaviour = str(point.get("behaviour", base.get("behaviour", DEFAULT_BEHAVIOUR)))
    for key in point:
        if key not in FIELDS and key not in params.names(behaviour):
            raise ScenarioError(
                f"--grid {key}: unknown scenario key; `touchswarm scenarios --behaviour "
                f"{behaviour}` lists the world's keys and the behaviour's")
    return validate(merge(base, point), "sweep point " + ", ".join(
        f"{k}={v}" for k, v in point.items()))


def pick_engine(engine: str) -> str:
    """The engine `auto` stands for: the struct-of-arrays engine, whatever the
    behaviour and rules (every rule of the reference runs in it)."""
    return "soa" if engine == "auto" else engine


def warm(scenarios: Iterable[Scenario], engine: str = "auto",
         on_compile: Callable[[str, Path], None] | None = None) -> list[str]:
    """Compile, or load from the disk cache, the soa engine's step for every
    behaviour of `scenarios`, in this process, before runs go to workers
    (forked workers inherit it; spawned ones find it on disk). A no-op for
    the other engines. on_compile(behaviour, cache folder) is called before a
    compile the cache does not hold (minutes); returns those behaviours."""
    if pick_engine(engine) != "soa":
        return []
    from sim_backend.batch.soa import warm as soa_warm
    return soa_warm(scenarios, on_compile)


# the background compile's process: the scenarios (one per behaviour) come
# pickled on stdin; the last line on stderr of a failure is its reason
COMPILE_MAIN = "from sim_backend.sweep import _compile_main; _compile_main()"


# the background compile's niceness: the sweep's reference runs, which the
# user waits for, take the cores first and the compile the rest. A sweep short
# enough to end before the compile (a 20-seed sweep: seconds against minutes)
# gets its runs done sooner; a long one loses little, its reference runs doing
# the work meanwhile; a sweep that ends leaves the compile the idle machine
COMPILE_NICE = 10


def _compile_main() -> None:
    import pickle
    import sys
    import traceback
    if hasattr(os, "nice"):
        os.nice(COMPILE_NICE)
    scenarios, held = pickle.load(sys.stdin.buffer)
    try:
        from sim_backend.batch.soa import adopt_lock, warm as soa_warm
        for folder, fd in held:
            adopt_lock(Path(folder), fd)
        soa_warm(scenarios)
    except BaseException as err:      # noqa: BLE001 - reported to the sweep in one line
        traceback.print_exc()
        print(one_line(err), file=sys.stderr, flush=True)
        sys.exit(1)


def one_line(err: BaseException) -> str:
    """`Type: first line of the message`."""
    first = (str(err).strip().splitlines() or [""])[0]
    return f"{type(err).__name__}: {first}" if first else type(err).__name__


class _Refused:
    """A background compile that could not start: the transform refused the
    behaviour (or failed) in this process already."""
    pid = None
    seconds = 0.0

    def __init__(self, err: BaseException) -> None:
        self.error = one_line(err)

    def finished(self) -> bool:
        return True


class BackgroundCompile:
    """The soa engine's compile of the behaviours of `scenarios`, in a
    separate process (`python -c COMPILE_MAIN`: it holds its own GIL, not
    the sweep's), started at once. finished() does not block; after it
    returns True, `error` is None or the failure in one line and `seconds`
    how long it took. A sweep that ends first leaves it running: it fills
    the disk cache for the next sweep. `claims` (cache folder -> the open
    file of its compile lock, soa.claim_lock) go to the process, which holds
    them until it ends: another sweep watches it instead of starting a
    compile of its own (the caller closes its copies). Two at once compile
    once: the second waits on the compile lock (soa.compile_lock) and then
    loads."""

    def __init__(self, scenarios: Sequence[Scenario],
                 claims: Mapping[Path, IO[str]] | None = None) -> None:
        import pickle
        import subprocess
        import sys
        import tempfile
        import time
        first: dict[str, Scenario] = {}
        for sc in scenarios:
            first.setdefault(str(sc.behaviour), sc)
        self.behaviours = list(first)
        self._clock = time.monotonic
        self._err = tempfile.TemporaryFile()
        root = str(Path(__file__).resolve().parents[1])
        env = dict(os.environ)
        env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH")) if p)
        self.t0 = self._clock()
        held = [(str(folder), f.fileno()) for folder, f in (claims or {}).items()]
        self.proc = subprocess.Popen([sys.executable, "-c", COMPILE_MAIN],
                                     stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                     stderr=self._err, env=env,
                                     pass_fds=[fd for _, fd in held] if os.name == "posix"
                                     else ())
        assert self.proc.stdin is not None
        self.proc.stdin.write(pickle.dumps((list(first.values()),
                                            held if os.name == "posix" else [])))
        self.proc.stdin.close()
        self.pid = self.proc.pid
        self.error: str | None = None
        self.seconds: float | None = None

    def finished(self) -> bool:
        if self.seconds is not None:
            return True
        rc = self.proc.poll()
        if rc is None:
            return False
        self.seconds = self._clock() - self.t0
        if rc != 0:
            self.error = self._reason(rc)
        self._err.close()
        return True

    def wait(self) -> bool:
        """Block until the compile ends (for callers that want it, not sweeps)."""
        self.proc.wait()
        return self.finished()

    def _reason(self, rc: int) -> str:
        if rc < 0:
            return f"the compile process was killed by signal {-rc}"
        self._err.seek(0)
        lines = [ln.strip() for ln in self._err.read().decode(errors="replace").splitlines()
                 if ln.strip()]
        return lines[-1] if lines else f"the compile process exited with status {rc}"


class _Watch:
    """A compile another process is running (it holds the compile lock of
    every step this sweep lacks: another sweep's background compile):
    watched, not started again. It has ended when no process holds the
    locks; well if the cache holds the steps then."""

    def __init__(self, scenarios: Sequence[Scenario], folders: Sequence[Path], pid: int) -> None:
        import time
        self.scenarios, self.folders, self.pid = scenarios, folders, pid
        self._clock = time.monotonic
        self.t0 = self._clock()
        self.error: str | None = None
        self.seconds: float | None = None

    def finished(self) -> bool:
        from sim_backend.batch.soa import cold, lock_holder
        if self.seconds is not None:
            return True
        if any(lock_holder(f) is not None for f in self.folders):
            return False
        self.seconds = self._clock() - self.t0
        if cold(self.scenarios):
            self.error = f"the compile in process {self.pid} ended without the step"
        return True


def _start_or_watch(scenarios: Sequence[Scenario], missing: Mapping[str, Path],
                    background: Callable[..., Any]) -> Any:
    """The background compile of the steps `missing` (behaviour -> cache
    folder): started, holding the compile locks this sweep could claim,
    or, when another process holds every one of them (another sweep's
    compile), watched."""
    from sim_backend.batch.soa import claim_lock, lock_holder
    folders = list(dict.fromkeys(missing.values()))
    mine: dict[Path, IO[str]] = {}
    held = []                            # by another process
    for d in folders:
        try:
            f = claim_lock(d)
        except OSError as err:           # a cache this user cannot write: nothing to share
            log.debug("no compile lock in %s (%s)", d, err)
            continue
        if f is None:
            held.append(d)
        else:
            mine[d] = f
    if held and len(held) == len(folders):
        pids = [p for p in map(lock_holder, held) if p is not None]
        return _Watch(scenarios, held, pids[0] if pids else -1)
    try:
        return background(scenarios, mine)
    finally:
        for f in mine.values():          # the compile's process holds its own copies
            f.close()


def _cold(scenarios: Sequence[Scenario]) -> dict[str, Path]:
    """soa.cold: the behaviours whose step the disk cache lacks, each with its
    cache folder; on an empty cache (nothing compiled, no compile under way)
    every behaviour, each with the cache's root, without generating the
    transform and importing numba in this process (0.7 s of CPU before the
    first run; the compile's process does both). The soa engine's modules
    (numpy's among them) are imported with the collector off: what they make
    lives as long as the process, and the collector's 26 passes over it
    found nothing (0.01-0.015 s of a sweep's start); it goes to the oldest
    generation after, as a build's does (soa._aged)."""
    import gc
    if gc.isenabled():
        gc.disable()
        try:
            from sim_backend.batch import soa
        finally:
            gc.enable()
        soa._aged()
    from sim_backend.batch.soa import cache_root, cold
    root = cache_root()
    if root.is_dir() and any(root.iterdir()):
        return cold(scenarios)
    return {str(sc.behaviour): root for sc in scenarios}


def _local(executor: Executor | None) -> bool:
    """Whether the executor's workers run on this machine (and so see the
    disk cache a background compile fills)."""
    from concurrent.futures import ThreadPoolExecutor
    return executor is None or isinstance(executor, (ProcessPoolExecutor, ThreadPoolExecutor))


class EngineStatus:
    """What a sweep's engine is doing, for progress lines: pass it as the
    sweep's on_event; note() is the text a progress line ends with."""

    def __init__(self, clock: Callable[[], float] | None = None) -> None:
        import time
        self.clock = clock or time.monotonic
        self.kind: str | None = None
        self.since = self.clock()

    def __call__(self, kind: str, text: str) -> None:
        self.kind, self.since = kind, self.clock()

    def note(self) -> str:
        if self.kind == "compiling":
            return (f"reference engine while soa compiles in the background "
                    f"({_duration(self.clock() - self.since)})")
        if self.kind == "compiled":
            return "soa engine (compiled in the background)"
        if self.kind == "failed":
            return "reference engine (the soa compile failed)"
        return ""


class _Engines:
    """The engine each new chunk runs in: `engine`, or, with a background
    compile, reference until it ends well and soa after (reference for good
    when it fails). Tells on_event(kind, text) and the log of each change."""

    def __init__(self, engine: str, bg: Any = None,
                 on_event: Callable[[str, str], None] | None = None) -> None:
        self.fixed = pick_engine(engine)
        self.bg = bg
        self.on_event = on_event
        self.state = "compiling" if bg is not None else None

    def tell(self, kind: str, text: str) -> None:
        (log.warning if kind == "failed" else log.info)("%s", text)
        if self.on_event is not None:
            self.on_event(kind, text)

    def poll(self, then: str = "the runs not started yet go to it") -> str:
        if self.state == "compiling" and self.bg.finished():
            if self.bg.error:
                self.state = "failed"
                self.tell("failed", f"the soa engine's compile failed ({self.bg.error}); "
                                    "the sweep finishes in the reference engine")
            else:
                self.state = "compiled"
                self.tell("compiled", f"the soa engine compiled in the background in "
                                      f"{_duration(self.bg.seconds or 0.0)}; {then}")
        if self.state is None:
            return self.fixed
        return "soa" if self.state == "compiled" else "reference"

    def chunk_size(self, engine: str, chunk_size: int, left: int, workers: int) -> int:
        """Runs in the next chunk, `left` runs not given to one yet. Under a
        background compile the reference chunks shrink towards the end, each
        at most half a worker's share of what is left, so that the workers end
        together (a 20-seed sweep on 2 workers in chunks of 4: one worker
        would run 12 runs while the other ran 8)."""
        if self.state is None or engine != "reference":
            return chunk_size
        if workers > 1:
            return max(1, min(chunk_size, REFERENCE_CHUNK, left // (2 * workers)))
        return min(chunk_size, REFERENCE_CHUNK)

    def end(self) -> None:
        if self.state == "compiling" and not self.bg.finished():
            self.tell("left", f"the soa compile goes on in the background (pid {self.bg.pid}) "
                              "and fills the disk cache for the next sweep")
        else:
            self.poll("the next sweep starts in it")


# runs per chunk when the caller gives none: at most this many, and as many
# chunks as the executor has workers (CHUNKS_PER_WORKER each), so that both
# cores of a 2-core machine help from ~20 runs up; one each: a chunk's
# build, first tick and summaries have costs of their own, which a second
# chunk per worker paid again (docs/performance.md)
MAX_CHUNK = 256
CHUNKS_PER_WORKER = 1


# a sweep of at most this many robots in all (20 seeds of 20 robots: 400)
# runs in this process when no chunk size is given, not in a process pool:
# its runs are a fraction of a second in the soa engine, less than a worker's
# start, its own build of the engine and load of the compiled step
SMALL_SWEEP_ROBOTS = 1000


def _small(executor: Executor | None, engine: str, scenarios: Sequence[Scenario]) -> bool:
    """Whether the sweep's runs cost less in this process (whose soa step is
    loaded) than spread over the process pool `executor`."""
    return (isinstance(executor, ProcessPoolExecutor) and engine == "soa"
            and sum(sc.agents for sc in scenarios) <= SMALL_SWEEP_ROBOTS)


def workers_of(executor: Executor | None) -> int:
    """How many runs `executor` steps at once (None: this process, one)."""
    if executor is None:
        return 1
    return getattr(executor, "_max_workers", None) or os.cpu_count() or 1


def chunk_runs(runs: int, executor: Executor | None = None) -> int:
    """The runs per chunk of a sweep of `runs` runs on `executor` (None:
    this process, one chunk of up to MAX_CHUNK)."""
    workers = workers_of(executor)
    if workers == 1:
        return max(1, min(MAX_CHUNK, runs))
    return max(1, min(MAX_CHUNK, -(-runs // (workers * CHUNKS_PER_WORKER))))


def run_chunk(jobs: Sequence[tuple[dict, dict, int]], engine: str = "auto",
              until: str = "delivered", progress_queue: Any = None, chunk_id: int = 0,
              report: Callable[[int], None] | None = None) -> list[dict]:
    """Run (base scenario dict, point params, seed) jobs; return one summary each.

    A plain top-level function, so every executor can ship it. Progress per
    finished run: report(k) in this process, or (chunk_id, k) put on
    progress_queue from a worker, k the runs of this chunk finished so far.
    """
    if report is None and progress_queue is not None:
        report = _queue_reporter(progress_queue, chunk_id)
    scs = _scenarios(jobs)
    seeds = [s for _, _, s in jobs]
    engine = pick_engine(engine)
    if engine == "soa":     # the struct-of-arrays transform, cached on disk
        return _soa_chunk(scs, seeds, until, report)
    if engine != "reference":
        raise ValueError(f"engine: expected one of {ENGINES}, got {engine!r}")
    from sim_backend.engine import Engine
    out = []
    for sc, seed in zip(scs, seeds):
        out.append(Engine(sc, seed, until=until).run().summary())
        if report is not None:
            report(len(out))
    return out


def _soa_chunk(scs: list[Scenario], seeds: list[int], until: str,
               report: Callable[[int], None] | None) -> list[dict]:
    """run_batch's summaries with the collector off: a chunk's runs and
    summaries make no garbage cycle, and its passes over what they make
    (some 80 in a 250-run chunk, gen. 0 and 1; soa keeps the batch itself
    out of them) found nothing in the default scenario's chunks, sync or
    netlogo: 0.01-0.035 s of a chunk's 0.8-1 s of CPU. Whatever a
    behaviour's runs did leave in a cycle waits for the next pass after the
    chunk."""
    import gc
    from sim_backend.batch.soa import run_batch
    collecting = gc.isenabled()
    gc.disable()
    try:
        return run_batch(scs, seeds, until=until, progress=report)
    finally:
        if collecting:
            gc.enable()


def _scenarios(jobs: Sequence[tuple[dict, dict, int]]) -> list[Scenario]:
    """The scenario of every job, validated once per run of jobs with the same
    base and point (a chunk is mostly one point's seeds; a Scenario is frozen,
    so they share it)."""
    out: list[Scenario] = []
    last: tuple[dict, dict] | None = None
    for b, p, _ in jobs:
        if last is None or not (last[0] is b or last[0] == b) or last[1] != p:
            sc = _scenario(b, p)
            last = (b, p)
        out.append(sc)
    return out


def _queue_reporter(q: Any, chunk_id: int) -> Callable[[int], None]:
    """report(k) that puts (chunk_id, k) on q only when k changes: the batch
    engines call it every tick, a manager queue is a round trip per put."""
    last = [0]

    def report(k: int) -> None:
        if k != last[0]:
            last[0] = k
            q.put((chunk_id, k))
    return report


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
        try:
            from distributed import Client
        except ImportError:
            raise ValueError(f"executor {spec}: needs dask.distributed, which is not "
                             "installed; pip install 'touchswarm[dask]'") from None
        # dask's own connect retries for 30 s and then raises from deep inside;
        # a plain TCP connect tells a wrong address at once
        try:
            with socket.create_connection((host, port), timeout=CONNECT_TIMEOUT_S):
                pass
        except OSError as err:
            raise ValueError(f"executor {spec}: no dask scheduler reachable at {host}:{port} "
                             f"({err.strerror or err}); start one with `dask scheduler` or "
                             "use --executor processes") from None
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
    base_d = base_dict(base, overrides)
    for pt in points:
        sc = _scenario(base_d, pt.as_dict())
        if link_faults(sc):
            raise ScenarioError(f"{link_faults(sc)[0]}: a link fault applies over "
                                "`touchswarm run --link can`; sweeps run in process")


def run_key(row: dict) -> tuple[str, str, str]:
    """(experiment, point, seed) of a row, as text: the identity of one run,
    the same for a row in memory and one read back from sweep.csv."""
    return (str(row["experiment"]), str(row["point"]), str(row["seed"]))


def _point_text(pt: Point) -> str:
    return ";".join(f"{k}={v}" for k, v in pt.params)


def _cell(v: Any) -> str:
    """A value as sweep.csv writes it."""
    return "" if v is None else str(v)


def sweep(points: Sequence[Point], seeds: Iterable[int], base: Scenario | None = None,
          engine: str = "auto", executor: Executor | None = None, until: str = "delivered",
          chunk_size: int | None = None, overrides: dict[str, Any] | None = None,
          progress: Callable[[int], None] | None = None,
          on_rows: Callable[[list[dict]], None] | None = None,
          done: Sequence[dict] = (),
          on_compile: Callable[[str, Path], None] | None = None,
          compile_first: bool = True,
          on_event: Callable[[str, str], None] | None = None,
          background: Callable[[Sequence[Scenario]], Any] | None = None) -> list[dict]:
    """Run every point with every seed; return tidy rows in point, seed order.

    engine: soa (compile the soa step first if the disk cache lacks it, then
      run in it), reference, or auto: soa when the cache holds the step;
      when it does not (and the executor is local), the runs start at once
      in the reference engine while `background(scenarios)` compiles the
      step in another process, and the chunks started after it ends run in
      soa (rows may mix: bit-identical engines; each row's `engine` says
      which ran it). A compile that fails leaves the sweep in the reference
      engine. A dask executor's workers do not share this machine's cache:
      auto compiles first there, as soa does.
    executor: any concurrent.futures.Executor (None: run in this process;
      a process pool too when the runs in the soa engine have at most
      SMALL_SWEEP_ROBOTS robots in all and chunk_size is None).
    chunk_size: runs per chunk (one call of run_chunk); None: chunk_runs().
    overrides: scenario keys applied to every point (e.g. maxTicks).
    progress: called with the number of runs just finished, as each run
      finishes (from process and thread pools too; other executors, e.g.
      dask, report when a chunk returns).
    on_rows: called with each chunk's rows as soon as the chunk returns, in
      the order chunks finish (the CLI appends them to sweep.csv).
    done: rows of runs already made (a resumed sweep's sweep.csv); those runs
      are checked against this sweep (check_done) and not run again; the
      result holds only the new runs.
    on_compile: told (behaviour, cache folder) before the soa engine compiles
      a behaviour its disk cache does not hold in this process (see warm).
    compile_first: False when the caller ran warm itself.
    on_event: told (kind, one-line text) of a background compile: kind
      "compiling" when it starts, "compiled" or "failed" when it ends,
      "left" when the sweep ends first (EVENTS); the log hears them too.
    background: starts the background compile (default BackgroundCompile;
      tests pass a fake), called with the scenarios and the compile locks
      this sweep claimed for it (folder -> open file; closed when it
      returns): an object with pid and finished() -> bool, then error
      (None or the reason in one line) and seconds.
    """
    if engine not in ENGINES:
        raise ValueError(f"engine: expected one of {ENGINES}, got {engine!r}")
    if chunk_size is not None and (isinstance(chunk_size, bool)
                                   or not isinstance(chunk_size, int) or chunk_size < 1):
        raise ValueError(f"chunk_size: expected at least 1 run per chunk, got {chunk_size!r}")
    seeds = list(seeds)
    check_seeds(seeds)
    if not points:
        raise ScenarioError("sweep: no grid points; expected at least one")
    base_d = base_dict(base, overrides)
    skip = check_done(done, points, seeds, base_d, until)
    jobs: list[tuple[dict, dict, int]] = []
    meta: list[tuple[Point, Scenario, int]] = []
    for pt in points:
        sc = _scenario(base_d, pt.as_dict())        # validate every point up front
        for s in seeds:
            if (pt.experiment, _point_text(pt), str(s)) in skip:
                continue
            jobs.append((base_d, pt.as_dict(), s))
            meta.append((pt, sc, s))
    scenarios = [sc for _, sc, _ in meta]
    bg: Any = None           # a compile started, watched or refused (_Engines' bg)
    if jobs and engine == "auto" and _local(executor):
        try:
            missing = _cold(scenarios)
        except Exception as err:       # e.g. a CompileError: auto runs the reference
            missing, bg = {}, _Refused(err)
            plan = _Engines(engine, bg, on_event)
        if missing:
            bg = _start_or_watch(scenarios, missing, background or BackgroundCompile)
            names = ", ".join(repr(b) for b in missing)
            where = ", ".join(str(d) for d in missing.values())
            plan = _Engines(engine, bg, on_event)
            plan.tell("compiling", f"the soa engine for behaviour {names} is not compiled yet "
                                   f"(once per machine and behaviour source, {SOA_COLD_COMPILE}):"
                                   f" the runs start now in the reference engine while it "
                                   f"compiles in the background (pid {bg.pid}; cache {where})")
    if bg is None:
        plan = _Engines(engine)
        if jobs and compile_first:
            warm(scenarios, engine, on_compile)
        if chunk_size is None and _small(executor, plan.fixed, scenarios):
            executor = None
    if chunk_size is None:
        chunk_size = chunk_runs(len(jobs), executor)
    rows: list[dict | None] = [None] * len(jobs)
    todo = list(range(len(jobs)))          # job indices not yet given to a chunk
    workers = workers_of(executor)

    def next_chunk() -> tuple[list[int], str]:
        eng = plan.poll()
        n = plan.chunk_size(eng, chunk_size, len(todo), workers)
        ch = todo[:n]
        del todo[:n]
        return ch, eng

    heads: dict[tuple[int, int], tuple[dict[str, Any], list[str]]] = {}

    def head(j: int) -> tuple[dict[str, Any], list[str]]:
        pt, sc, _ = meta[j]               # meta keeps both alive: their ids stay theirs
        key = (id(pt), id(sc))
        if key not in heads:
            heads[key] = row_head(pt, sc)
        return heads[key]

    def finish(ch: list[int], eng: str, sums: list[dict]) -> None:
        new = [make_row(*meta[j], summ, until, eng, head(j)) for j, summ in zip(ch, sums)]
        for j, r in zip(ch, new):
            rows[j] = r
        if on_rows is not None:
            on_rows(new)

    try:
        if executor is None:
            while todo:
                ch, eng = next_chunk()
                told = [0]

                def report(k: int, told: list[int] = told) -> None:
                    if progress is not None and k > told[0]:
                        progress(k - told[0])
                        told[0] = k
                sums = run_chunk([jobs[j] for j in ch], eng, until, report=report)
                report(len(ch))
                finish(ch, eng, sums)
        else:
            # with a background compile, a chunk's engine is chosen when a
            # worker is free for it; otherwise every chunk goes at once
            limit = None
            if bg is not None:
                limit = workers
            # the objects this process holds now (numba and the loaded step
            # among them) out of the collector's sight while the workers fork:
            # a forked worker's collections no longer walk them (nor copy
            # their pages by touching their counts): a tenth of its CPU
            import gc
            forks = isinstance(executor, ProcessPoolExecutor)
            if forks:
                gc.freeze()
            try:
                _run_on(executor, next_chunk, lambda: bool(todo), jobs, until, progress,
                        finish, limit, plan.poll)
            finally:
                if forks:
                    gc.unfreeze()
    finally:
        plan.end()
    return rows  # type: ignore[return-value]


def _progress_queue(executor: Executor) -> tuple[Any, Callable[[], None]]:
    """A queue the executor's workers can put progress on, and its closer;
    (None, noop) for executors whose workers cannot reach one (dask)."""
    from concurrent.futures import ThreadPoolExecutor
    if isinstance(executor, ThreadPoolExecutor):
        import queue
        return queue.Queue(), (lambda: None)
    if isinstance(executor, ProcessPoolExecutor):
        if sys.platform == "linux":
            inbox = _Inbox()
            return inbox, inbox.close
        import multiprocessing
        manager = multiprocessing.Manager()
        return manager.Queue(), manager.shutdown
    return None, (lambda: None)


class _Inbox:
    """Progress from worker processes as datagrams on a Unix socket this
    process reads: no Manager server process to fork and stop (a copy of
    this process, numba loaded). Abstract-namespace (Linux): nothing on disk,
    and any worker reaches it by its address, however the pool started it.
    A full socket drops what a worker sends; harmless, since each message
    is a chunk's count so far and its result brings the final one."""

    def __init__(self) -> None:
        self._sock = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
        self._sock.bind("")                 # an unused abstract address
        self._sock.setblocking(False)
        self.address: bytes = self._sock.getsockname()

    def __reduce__(self) -> tuple[type, tuple[bytes]]:
        return _Outbox, (self.address,)     # what a worker gets

    def get_nowait(self) -> tuple[int, int]:
        import queue
        try:
            data = self._sock.recv(_PROGRESS.size)
        except BlockingIOError:
            raise queue.Empty from None
        return _PROGRESS.unpack(data)

    def close(self) -> None:
        self._sock.close()


class _Outbox:
    """A worker's end of an _Inbox: put((chunk_id, k)) never blocks."""

    def __init__(self, address: bytes) -> None:
        self.address = address

    def put(self, item: tuple[int, int]) -> None:
        if not _OUTBOX_SOCKET:              # one unbound socket reaches any inbox
            _OUTBOX_SOCKET.append(socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM))
            _OUTBOX_SOCKET[0].setblocking(False)
        try:
            _OUTBOX_SOCKET[0].sendto(_PROGRESS.pack(*item), self.address)
        except (BlockingIOError, ConnectionRefusedError):   # full, or the sweep ended
            pass


_PROGRESS = struct.Struct("<qq")                       # (chunk_id, k)
_OUTBOX_SOCKET: list[socket.socket] = []               # a worker process's


def _run_on(executor: Executor, next_chunk: Callable[[], tuple[list[int], str]],
            more: Callable[[], bool], jobs: list, until: str,
            progress: Callable[[int], None] | None,
            finish: Callable[[list[int], str, list[dict]], None],
            limit: int | None = None, poll: Callable[[], Any] = lambda: None) -> None:
    """Submit chunks (at most `limit` running at once, None: all at once);
    report runs as they finish, rows as chunks return; poll() between."""
    import queue as queue_mod
    from concurrent.futures import FIRST_COMPLETED, wait
    q, close = _progress_queue(executor) if progress is not None else (None, lambda: None)
    told: dict[int, int] = {}
    futs: dict[Future, tuple[int, list[int], str]] = {}

    def tell(i: int, k: int) -> None:
        if k > told.get(i, 0):
            progress(k - told.get(i, 0))  # type: ignore[misc]
            told[i] = k

    def submit() -> None:
        while more() and (limit is None or len(futs) < limit):
            ch, eng = next_chunk()
            i = len(told)
            told[i] = 0
            futs[executor.submit(run_chunk, [jobs[j] for j in ch], eng, until, q, i)] = \
                (i, ch, eng)
    try:
        submit()
        while futs:
            # the timeout only bounds how stale the per-run progress (and
            # the news of a background compile) gets
            timeout = 0.5 if q is not None or limit is not None else None
            finished, _ = wait(set(futs), timeout=timeout, return_when=FIRST_COMPLETED)
            while q is not None:
                try:
                    i, k = q.get_nowait()
                except queue_mod.Empty:
                    break
                tell(i, k)
            poll()
            for f in finished:
                i, ch, eng = futs.pop(f)
                sums = f.result()
                if progress is not None:
                    tell(i, len(ch))
                finish(ch, eng, sums)
            submit()
    finally:
        close()


def check_done(done: Sequence[dict], points: Sequence[Point], seeds: Sequence[int],
               base_d: dict[str, Any], until: str) -> set[tuple[str, str, str]]:
    """The run keys of `done` rows, each checked to be a run of this sweep
    with the same scenario values; ScenarioError naming the first that is not."""
    runs: dict[tuple[str, str, str], Scenario] = {}
    for pt in points:
        sc = _scenario(base_d, pt.as_dict())
        for s in seeds:
            runs[(pt.experiment, _point_text(pt), str(s))] = sc
    keys: set[tuple[str, str, str]] = set()
    for n, row in enumerate(done, start=2):
        key = run_key(row)
        where = f"row {n} ({key[1]}, seed {key[2]})"
        if key not in runs:
            raise ScenarioError(f"resume: {where} is not a run of this sweep; it was "
                                "written by another grid or seed list: use another --out")
        if key in keys:
            raise ScenarioError(f"resume: {where} is there twice; the file was edited")
        sc = runs[key]
        for k in [*SCENARIO_KEYS, *dict(sc.params)]:
            if _cell(row.get(k)) != _cell(getattr(sc, k)):
                raise ScenarioError(f"resume: {where} has {k}={row.get(k)} but this sweep "
                                    f"runs {k}={getattr(sc, k)!r}; use another --out or the "
                                    "same settings")
        if _cell(row.get("until")) != until:
            raise ScenarioError(f"resume: {where} ran until {row.get('until')!r}, this sweep "
                                f"until {until!r}; use another --out or the same --until")
        keys.add(key)
    return keys


def columns(behaviours: Iterable[str]) -> list[str]:
    """sweep.csv's columns, in order, for rows of these behaviours: the
    fixed ones, then each behaviour's declared measures not already there."""
    from sim_backend import registry
    names = ["experiment", "point", *SCENARIO_KEYS, "pieces", "breeds", "required", "seed",
             "until", "engine",
             *MEASURES]
    from sim_backend import params
    at = names.index("pieces")
    for b in dict.fromkeys(behaviours):
        for name in params.names(b):
            if name not in names:
                names.insert(at, name)
                at += 1
    for b in dict.fromkeys(behaviours):
        for name, _ in registry.load(b).spec.MEASURES:
            if name not in names:
                names.append(name)
    return names


def point_scenarios(points: Sequence[Point], base: Scenario | None = None,
                    overrides: dict[str, Any] | None = None) -> list[Scenario]:
    """The scenario of every point, in order."""
    base_d = base_dict(base, overrides)
    return [_scenario(base_d, pt.as_dict()) for pt in points]


def point_behaviours(points: Sequence[Point], base: Scenario | None = None,
                     overrides: dict[str, Any] | None = None) -> list[str]:
    """The behaviour of every point, in order, each once."""
    return list(dict.fromkeys(sc.behaviour for sc in point_scenarios(points, base, overrides)))


def row_head(pt: Point, sc: Scenario) -> tuple[dict[str, Any], list[str]]:
    """What a sweep.csv row takes from its point alone (its settings; the
    same for every seed) and the names of the measures its behaviour
    declares: make_row's `head`, made once per point by a sweep."""
    row: dict[str, Any] = {"experiment": pt.experiment,
                           "point": ";".join(f"{k}={v}" for k, v in pt.params)}
    for k in SCENARIO_KEYS:
        row[k] = getattr(sc, k)
    row.update(sc.params)
    row["pieces"] = " ".join(repr(p) for k in PIECE_KEYS for p in getattr(sc, k))
    row["breeds"] = " ".join(f"{dict(b)['name']}:{dict(b)['count']}" for b in sc.breeds)
    row["required"] = holders_needed(sc, sc.weight_centi)
    from sim_backend import registry
    return row, [name for name, _ in registry.load(sc.behaviour).spec.MEASURES]


def make_row(pt: Point, sc: Scenario, seed: int, s: dict, until: str,
             engine: str = "reference",
             head: tuple[dict[str, Any], list[str]] | None = None) -> dict:
    """One sweep.csv row: the run's settings, the engine that ran it, its
    measures (head: row_head(pt, sc), made here when not given)."""
    settings, measures = head or row_head(pt, sc)
    row = dict(settings)
    row["seed"] = seed
    row["until"] = until
    row["engine"] = engine
    row["ticks"] = s["ticks"]
    row["n_touches"] = len(s["touches"])
    row["delivered"] = s["delivered"]
    # the holders' rounded positions (the host contract; the thesis's shape.txt)
    row["touches"] = _cells(s["touches"])
    # the host's shape estimate and verdict (perception/tracker.py end_fields;
    # empty for a behaviour that perceives no object)
    for name in ("estimate_iou", "recognised", "p"):
        row[name] = s.get(name)
    # the measures the behaviour declares (spec.MEASURES), and only those:
    # a dispersion sweep has no power or shape_iou column
    for name in measures:
        if name not in row:
            v = s.get(name)
            row[name] = _cells(v) if isinstance(v, list) else v
    return row


def _cells(pairs: list) -> str:
    """A list of (x, y) cells as one CSV field, "x:y x:y"."""
    return " ".join(f"{x}:{y}" for x, y in pairs)


def write_csv(rows: Sequence[dict], path: Path, names: Sequence[str] | None = None) -> Path:
    """Every row under one header (names, default: every key of the rows,
    in first-seen order), written to a temporary file and moved into place."""
    def write(f: IO[str]) -> None:
        if rows or names:
            # rows of different behaviours carry different measures: every column once
            cols = list(names or dict.fromkeys(k for r in rows for k in r))
            wr = csv.writer(f, lineterminator="\n")
            wr.writerow(cols)
            wr.writerows(_lines(rows, cols))
    return _replace(path, write)


def _replace(path: Path, write: Callable[[IO[str]], None]) -> Path:
    """path made by write(file): in a temporary file moved into place, so
    that a reader never sees it half written."""
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w", newline="") as f:
        write(f)
    os.replace(tmp, path)
    return path


def _lines(rows: Iterable[dict], names: Sequence[str]) -> Iterator[list[str]]:
    """Each row's cells in the order of `names` (empty where it has none);
    ValueError naming a column of a row that `names` lacks."""
    known = set(names)
    for r in rows:
        if not known.issuperset(r):
            raise ValueError(f"a sweep row has columns sweep.csv's header lacks: "
                             f"{sorted(set(r) - known)}")
        yield list(map(_cell, map(r.get, names)))


def read_csv(path: Path) -> list[dict]:
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


class CsvAppender:
    """sweep.csv as a journal: the header once, then each row as its run
    returns, flushed and fsynced, so a killed sweep keeps every row written.

    resume=True keeps an existing file: its header must be `names`, and a
    last line cut off mid-write (no newline) is dropped (that run is made
    again). Otherwise the file is (re)written from the first append on, so
    a sweep that fails before its first run leaves no file behind.
    """

    def __init__(self, path: Path, names: Sequence[str], resume: bool = False) -> None:
        self.path = path
        self.names = list(names)
        self.f: Any = None
        self.written: list[dict] = []       # the rows appended, in order
        # the text of the header and of each append, with the append's rows:
        # rows that came back out of run order are put in order from these
        # (reorder), not formatted again
        self.header = ""
        self.blocks: list[tuple[Sequence[dict], str]] = []
        self.append_to = resume and path.exists() and path.stat().st_size > 0
        if self.append_to:
            _drop_partial_line(path)
            with path.open(newline="") as f:
                header = next(csv.reader(f), [])
            if header != self.names:
                extra = [n for n in header if n not in self.names] or \
                    [n for n in self.names if n not in header]
                raise ScenarioError(f"resume: {path} has other columns than this sweep writes"
                                    + (f" ({extra[0]!r})" if extra else "")
                                    + "; it comes from another sweep: use another --out")

    def append(self, rows: Sequence[dict]) -> None:
        import io
        if self.f is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self.f = self.path.open("a" if self.append_to else "w", newline="")
            self.buf = io.StringIO(newline="")
            self.writer = csv.writer(self.buf, lineterminator="\n")
            if not self.append_to:
                self.writer.writerow(self.names)
                self.header = self._taken()
                self.f.write(self.header)
        self.writer.writerows(_lines(rows, self.names))
        text = self._taken()
        self.f.write(text)
        self.f.flush()
        os.fsync(self.f.fileno())
        self.written += rows
        self.blocks.append((rows, text))

    def _taken(self) -> str:
        """What the writer wrote since the last call."""
        text = self.buf.getvalue()
        self.buf.seek(0)
        self.buf.truncate()
        return text

    def holds(self, rows: Sequence[dict]) -> bool:
        """Whether the file is what write_csv(rows, path, names) writes: this
        journal made it afresh and appended these very rows, in this order
        (a sweep whose chunks returned in run order need not write it again)."""
        return (self.f is not None and not self.append_to and len(rows) == len(self.written)
                and all(a is b for a, b in zip(rows, self.written)))

    def reorder(self, rows: Sequence[dict]) -> bool:
        """Make the file what write_csv(rows, path, names) writes when `rows`
        are this journal's own appends, each whole, in another order (chunks
        that returned out of run order): their texts put in that order, the
        rows not formatted again. False, the file untouched, otherwise."""
        if self.f is None or self.append_to or len(rows) != len(self.written):
            return False
        by_first = {id(b[0][0]): b for b in self.blocks if b[0]}
        order = []
        i = 0
        while i < len(rows):
            block = by_first.pop(id(rows[i]), None)
            if (block is None or len(block[0]) > len(rows) - i
                    or not all(a is b for a, b in zip(itertools.islice(rows, i, None), block[0]))):
                return False
            order.append(block[1])
            i += len(block[0])
        self.close()
        _replace(self.path, lambda f: f.writelines([self.header] + order))
        return True

    def close(self) -> None:
        if self.f is not None:
            self.f.close()


def _drop_partial_line(path: Path) -> None:
    """Cut a file back to its last newline (a row cut off by a kill)."""
    data = path.read_bytes()
    if data and not data.endswith(b"\n"):
        keep = data.rfind(b"\n") + 1
        log.warning("%s: dropping a last row cut off mid-write (%d bytes)", path,
                    len(data) - keep)
        with path.open("r+b") as f:
            f.truncate(keep)


def read_done(path: Path) -> list[dict]:
    """The rows of an interrupted sweep's sweep.csv (none if it is missing),
    a last line cut off mid-write left out."""
    if not path.exists():
        return []
    data = path.read_text()
    if data and not data.endswith("\n"):
        data = data[:data.rfind("\n") + 1]
    import io
    return list(csv.DictReader(io.StringIO(data)))


class ProgressLog:
    """Progress as plain lines, for a sweep whose output is not a terminal
    (a log file, CI, nohup): `done/total runs (pct), rate runs/s, ETA`.

    update(n) is called as each run finishes; a line goes to emit for the
    first run, then every `every_runs` runs (default: every 5% of the
    sweep) or once `every_s` seconds have passed since the last line,
    whichever comes first, and at the end. note() (e.g. EngineStatus.note)
    ends each line when it says something. clock is injectable so tests
    need no real time.
    """

    def __init__(self, total: int, emit: Callable[[str], None], already: int = 0,
                 every_runs: int | None = None, every_s: float = 10.0,
                 clock: Callable[[], float] | None = None,
                 note: Callable[[], str] | None = None) -> None:
        import time
        self.note = note
        self.total = total
        self.emit = emit
        self.already = already          # runs a resumed sweep found done
        self.done = already
        self.every_runs = every_runs or max(1, (total - already) // 20)
        self.every_s = every_s
        self.clock = clock or time.monotonic
        self.t0 = self.last_t = self.clock()
        self.last_done = already

    def update(self, n: int = 1) -> None:
        self.done += n
        now = self.clock()
        first = self.last_done == self.already
        if (first or self.done >= self.total or self.done - self.last_done >= self.every_runs
                or now - self.last_t >= self.every_s):
            self.emit(self.line(now))
            self.last_t, self.last_done = now, self.done

    def line(self, now: float) -> str:
        new = self.done - self.already
        dt = now - self.t0
        rate = new / dt if dt > 0 else 0.0
        left = self.total - self.done
        eta = _duration(left / rate) if rate > 0 else "?"
        pct = 100 * self.done / self.total if self.total else 100.0
        note = self.note() if self.note is not None else ""
        return (f"sweep: {self.done}/{self.total} runs ({pct:.0f}%), {rate:.2f} runs/s, "
                f"ETA {eta}" + (f"; {note}" if note else ""))


def _duration(s: float) -> str:
    s = int(round(s))
    h, rest = divmod(s, 3600)
    m, sec = divmod(rest, 60)
    return f"{h}h{m:02d}m{sec:02d}s" if h else (f"{m}m{sec:02d}s" if m else f"{sec}s")
