"""The batch engine: many runs stepped together by the behaviour's own
firmware source, transformed into struct-of-arrays functions and compiled.

The robots are built by their CPython constructors, packed into one array
per field, and stepped by `tick_all` of sim_backend/batch/body.py,
transformed (sim_backend/batch/transform.py) along with every method and
function it reaches; the world's rules are sim_backend/kernel.py, the
functions the reference engine runs. The generated module is written to a
cache directory keyed by a hash of its own text (`$TOUCHSWARM_CACHE` or
`~/.cache/touchswarm`, then `soa/<hash>/`) and compiled with
`njit(cache=True)`: a second process with the same sources loads the
machine code from disk instead of compiling it. A changed behaviour source
is a different text, so a different directory.

One compiled call steps a tick of every live run; the host coordinators stay
the behaviour's Python objects, fed the same messages in the same order as
the reference engine's in-process link feeds them, and asked to tick when
they received a message or their `wake` tick came (never while `quiet()`,
else `idle_until()`; a coordinator without either is asked every tick); a
message the coordinator declared `muted()` (one that would change nothing)
is not handed to it, as in the reference (sim_backend/exchange.py, the
rule both follow). A run stops where `Engine.run` stops it: delivered
(or, with until="converged", converged) or at its maxTicks. At a run's end
its final state goes into a World, and the robots' fields into their
CPython objects when its RunResult's robots are first read (a summary reads
none), so a RunResult holds the very robots and
world the reference engine holds, and every summary, record and picture is
the reference's.
"""

from __future__ import annotations

import gc
import hashlib
import importlib.util
import json
import logging
import os
import shutil
import sys
import threading
import time
import traceback
from collections import defaultdict
from contextlib import contextmanager
from functools import cached_property, partial
from itertools import chain
from pathlib import Path
from types import ModuleType
from typing import IO, Any, Callable, Iterable, Iterator, Sequence

import numpy as np

from firmware_logic import messages as msg
from sim_backend import registry
from sim_backend import kernel
from sim_backend.batch import body as B
from sim_backend.batch import transform as T
from sim_backend.engine import UNTIL, RunResult, declared_measures, run_ended
from sim_backend.errors import EngineError
from sim_backend.exchange import HEARS_ALL, NEVER, BatchMutes, exchange, wake
from sim_backend.scenario import Scenario
from sim_backend.world import World

log = logging.getLogger(__name__)

INBOX = 16            # messages a robot may have waiting (the host sends a few per tick)
SENDS_PER_ROBOT = 8   # messages a robot may send in one tick
PREFIX = "_touchswarm_soa_"
# a finished run's World: its grids (row k of the batch's grids is the
# World's attribute kernel.GRID_FIELDS[k]), robot rows and where its share
# of the batch's arrays lies
_WORLD_GRIDS = tuple(enumerate(kernel.GRID_FIELDS))
_ROBOT_ROWS = np.array([B.XS, B.YS, B.HELD])
_BOUNDS = np.array([B.LO, B.HI, B.C0, B.C1])
# batches of at most this many runs read their wake ticks as a list (_exchange)
_FEW_RUNS = 16
# zeros that fill a command's fields to a whole row of the inbox, by its field count
_PAD = tuple((0,) * (B.FIELDS - n) for n in range(B.FIELDS + 1))


def cache_root() -> Path:
    env = os.environ.get("TOUCHSWARM_CACHE")
    base = Path(env) if env else Path.home() / ".cache" / "touchswarm"
    return base / "soa"


class Compiled:
    """One generated module, loaded (its numba functions compile or load lazily)."""

    def __init__(self, source: str, names: dict[str, str]) -> None:
        digest = hashlib.sha256(source.encode()).hexdigest()[:20]
        self.digest = digest
        name = PREFIX + digest
        self.seconds = 0.0
        if name in sys.modules:
            self.module: ModuleType = sys.modules[name]
        else:
            folder = cache_root() / digest
            path = folder / "mod.py"
            if not path.exists() or path.read_text() != source:
                folder.mkdir(parents=True, exist_ok=True)
                tmp = folder / f"mod.{os.getpid()}.tmp"
                tmp.write_text(source)
                os.replace(tmp, path)        # atomic: another process may read it
            _without("numba", CFFI)
            spec = importlib.util.spec_from_file_location(name, path)
            assert spec is not None and spec.loader is not None
            mod = importlib.util.module_from_spec(spec)
            sys.modules[name] = mod          # numba pickles State by module name
            spec.loader.exec_module(mod)
            self.module = mod
            log.debug("soa module %s at %s", name, path)
        assert self.module.__file__ is not None     # loaded from its mod.py
        self.path = Path(self.module.__file__)
        self.names = names

    def on_disk(self, key: str) -> bool:
        """Whether numba's cache beside the module holds an entry's machine code."""
        return any((self.path.parent / "__pycache__").glob(
            f"{self.path.stem}.{self.names[key]}-*.nbi"))

    def entry(self, key: str) -> tuple[Any, tuple[str, ...]]:
        """An entry function and the names of its leading state arguments."""
        name = self.names[key]
        return getattr(self.module, name), getattr(self.module, name + "__STATE")

    def first_call(self, fn: Any, args: tuple, key: str | None = None) -> Any:
        """fn(*args), the call that compiles fn or loads it from the disk
        cache. numba raises on a cache file it cannot unpickle (a truncated
        or damaged index or data file) instead of compiling again; then the
        module's cache is deleted, a warning names it, and fn compiles.
        When entry `key` is not on disk yet the call holds the module's
        compile lock: processes that need the same step (a sweep's
        background compile, its workers, another sweep) compile it once,
        the others wait and load it."""
        _freeze_at_exit()
        if key is None or self.on_disk(key):
            with _loading_only(fn):
                return self._first_call(fn, args)
        _without(ARRAYMATH)
        with compile_lock(self.path.parent):
            return self._first_call(fn, args)

    def _first_call(self, fn: Any, args: tuple) -> Any:
        try:
            return fn(*args)
        except Exception as err:
            if not _from_numba_cache(err):
                raise
            folder = self.path.parent / "__pycache__"
            log.warning("the soa engine's disk cache %s could not be read (%s: %s); "
                        "compiling it again", folder, type(err).__name__, err)
            shutil.rmtree(folder, ignore_errors=True)
            return fn(*args)


_FREEZING: list[bool] = []


def _freeze_at_exit() -> None:
    """At this process's exit, every object out of the collector's sight:
    the interpreter's last collections would walk numba's heap of a loaded
    step (its types, IR and LLVM objects: a quarter second) to free memory
    the exit frees anyway."""
    if not _FREEZING:
        _FREEZING.append(True)
        import atexit
        atexit.register(gc.freeze)


@contextmanager
def _loading_only(fn: Any) -> Iterator[None]:
    """fn's first call without the refresh numba's disk cache runs before it
    loads an entry: the refresh installs every typing and lowering registry
    of the target (about 0.1-0.3 s, half a warm step's load), which only a
    compile reads, and a compile refreshes for itself (numba's CompilerBase),
    so a load that misses still compiles as before. Where fn's cache is not
    the numba 0.5x-0.6x one this was written against, fn's call is left
    as it is."""
    cache: Any = getattr(fn, "_cache", None)
    load = getattr(cache, "_load_overload", None)
    guard = getattr(cache, "_guard_against_spurious_io_errors", None)
    try:
        from numba.core.runtime import rtsys
    except ImportError:
        load = None
    if load is None or guard is None:
        _without(ARRAYMATH)              # before the refresh imports it
        yield
        return

    def load_overload(sig: Any, target_context: Any) -> Any:
        # the part of the refresh a loaded step needs: the runtime its
        # arrays' reference counts call (the refresh's first step)
        rtsys.initialize(target_context)
        data = None
        with guard():
            data = load(sig, target_context)
        if data is None:                 # not in the cache: a compile follows
            _without(ARRAYMATH)
        return data

    # one first call at a time (a thread pool's engines share the step's
    # dispatchers; numba compiles and loads one at a time anyway)
    with _FIRST_CALLS:
        cache.load_overload = load_overload
        try:
            yield
        finally:
            vars(cache).pop("load_overload", None)


_FIRST_CALLS = threading.RLock()


# numba modules imported with modules they ask for made unimportable: `_without`
ARRAYMATH, CFFI = "numba.np.arraymath", "numba.core.typing.cffi_utils"
_BLOCKED = {"numba": (("scipy", "scipy"), ("yaml", "yaml")),
            ARRAYMATH: (("scipy.linalg.cython_blas", "scipy.linalg"),),
            CFFI: (("cffi", "cffi"),)}
# numba reads its settings from this file in the working directory, with yaml
NUMBA_CONFIG_FILE = ".numba_config.yaml"


def _without(*modules: str) -> None:
    """Import numba's array maths without asking for scipy's BLAS (ARRAYMATH),
    and its typing of cffi functions without cffi (CFFI): a generated step
    is integers only (transform.py's subset) and calls neither. numba
    itself ("numba") imports scipy only to check its version (0.04 s), and
    yaml (90 M instructions, 0.02-0.03 s) only to read NUMBA_CONFIG_FILE,
    so yaml is blocked only while no such file is there to read.

    The maths asks once per process to choose np.correlate's and
    np.convolve's inner loop (the linear algebra asks again itself),
    importing scipy.linalg: a quarter second. Only a compile imports the
    maths (numba's refresh of its registries): a step loaded from the cache
    (_loading_only) needs none of it, 0.08 s of imports left out. The cffi
    typing imports cffi and pycparser (0.04-0.06 s) when numba's typing
    context first loads, at a step's first call; imported while cffi is
    unimportable it records that cffi is missing, as on a machine without it
    (numba then types no cffi function in this process). Each is blocked
    only while numba's module imports, only when nothing imported the real
    one first, so any other importer still gets it."""
    for module in modules:
        if module in sys.modules:
            continue
        stubs = [stub for stub, real in _BLOCKED[module]
                 if real not in sys.modules and not (real == "yaml"
                                                     and os.path.isfile(NUMBA_CONFIG_FILE))]
        for stub in stubs:
            sys.modules[stub] = None            # type: ignore[assignment]  # an ImportError
        try:
            importlib.import_module(module)
        finally:
            for stub in stubs:
                del sys.modules[stub]


# compile locks a sweep claimed (claim_lock) and handed to this process, its
# background compile: held until it exits, so compile_lock does not wait on them
_HELD: dict[Path, IO[str]] = {}


def _mark(f: IO[str], pid: int) -> None:
    f.seek(0)
    f.truncate()
    f.write(str(pid))                    # who compiles, for lock_holder
    f.flush()


@contextmanager
def compile_lock(folder: Path) -> Iterator[None]:
    """Hold `folder`/compile.lock (an flock: the kernel frees it when the
    holder dies) for the duration; no lock where fcntl is missing, none to
    take when this process was handed it (adopt_lock)."""
    held = _HELD.get(folder)
    if held is not None:
        _mark(held, os.getpid())
        yield
        return
    try:
        import fcntl
    except ImportError:          # not POSIX: compiles may overlap, numba copes
        yield
        return
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / "compile.lock", "a+") as f:
        fcntl.flock(f, fcntl.LOCK_EX)
        try:
            _mark(f, os.getpid())
            yield
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)


def claim_lock(folder: Path) -> IO[str] | None:
    """`folder`'s compile lock taken without waiting: the open file that holds
    it (closed, it frees the lock; inherited by a child process, it is the
    child's too), or None when another process holds it. Taking it is the
    test: two sweeps that find the same step missing at once cannot both
    see it free, as two lock_holder probes could before either compile
    began. Where fcntl is missing, an open file that locks nothing."""
    folder.mkdir(parents=True, exist_ok=True)
    f = open(folder / "compile.lock", "a+")
    try:
        import fcntl
    except ImportError:
        return f
    try:
        fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        f.close()
        return None
    _mark(f, os.getpid())
    return f


def adopt_lock(folder: Path, fd: int) -> None:
    """Hold, until this process exits, `folder`'s compile lock that the
    process which started it claimed (claim_lock) and passed as fd."""
    f = os.fdopen(fd, "a+")
    _mark(f, os.getpid())
    _HELD[folder] = f


def lock_holder(folder: Path) -> int | None:
    """The pid of the process that holds `folder`'s compile lock (compiling
    its step now; -1 when it wrote none yet), or None when no process does."""
    try:
        import fcntl
    except ImportError:
        return None
    path = folder / "compile.lock"
    if not path.exists():
        return None
    with open(path, "a+") as f:
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            f.seek(0)
            text = f.read().strip()
            return int(text) if text.isdigit() else -1
        fcntl.flock(f, fcntl.LOCK_UN)
        return None


def _from_numba_cache(err: BaseException) -> bool:
    """Whether err was raised while numba read its disk cache."""
    return any(Path(f.filename).parts[-3:] == ("numba", "core", "caching.py")
               for f in traceback.extract_tb(err.__traceback__))


_LOADED: dict[str, Compiled] = {}
# one batch's transform at a time: the threads of a sweep's thread pool each
# build an engine, and CPython 3.11's ast.parse is not thread-safe (two at
# once raised "SystemError: AST constructor recursion depth mismatch",
# python/cpython#106905)
_LOCK = threading.Lock()


def compile_batch(robots: list[Any], body: Any) -> tuple[T.Layout, Compiled, dict[str, Any]]:
    """Layout, compiled module and state arrays of a batch's robots and body."""
    with _LOCK:
        return _compile_batch(robots, body)


def _compile_batch(robots: list[Any], body: Any) -> tuple[T.Layout, Compiled, dict[str, Any]]:
    layout = T.Layout()
    layout.add(body)
    layout.add_all(robots)
    rcls = type(robots[0])
    body_cls = type(body)
    entries = {"tick_all": (B.tick_all, (T.ListOf(rcls), T.Inst(body_cls), T.SCALAR)),
               "states_of": (B.states_of, (T.ListOf(rcls), T.SCALAR)),
               # the host's exchange: each a few numpy calls' work in one call
               "sift": (B.sift, (T.SCALAR,) * 12),
               "deliver": (B.deliver, (T.SCALAR,) * 9)}
    source, names = generated(layout, entries)
    key = hashlib.sha256(source.encode()).hexdigest()
    comp = _LOADED.get(key)
    if comp is None:
        comp = _LOADED[key] = Compiled(source, names)
    return layout, comp, T.state_arrays(layout)


# generated texts by `T.shape`, with the inputs they were read from
_GENERATED: dict[str, tuple[str, dict[str, str], T.Inputs]] = {}
transforms = 0                   # how many times this process ran the transform


# key -> the process that last found _GENERATED[key]'s inputs unchanged (or
# made it); a forked worker's copy names its parent
_CHECKED: dict[str, int] = {}


def _checked_by_parent(key: str) -> bool:
    """Whether the process this one was forked from checked (or made) the
    text of `key` this one keeps in memory: a sweep's worker then takes it
    without reading every source file again. Its code is the parent's as
    it was then (a fork copies the imported modules; what changes on disk
    later is not what it runs), and it checks at its own next build. Only
    a fork copies the mark, so another pid in it is always an ancestor's."""
    pid = _CHECKED.get(key)
    return pid is not None and pid != os.getpid()


def generated(layout: T.Layout, entries: dict[str, tuple[Any, tuple]]
              ) -> tuple[str, dict[str, str]]:
    """T.generate(layout, entries), or the same text kept from an earlier
    build (this process's, or any process's in the cache folder's
    `generated/`) while every file and name it was read from is unchanged
    (T.Inputs): a warm engine skips the transform."""
    global transforms
    key = T.shape(layout, entries)
    kept = _GENERATED.get(key)
    inherited = kept is not None and _checked_by_parent(key)
    index = cache_root() / "generated" / f"{key}.json"
    if kept is None:
        try:
            d = json.loads(index.read_text())
            kept = d["source"], d["names"], T.Inputs.from_json(d)
        except (OSError, ValueError, KeyError, TypeError, IndexError):
            kept = None
    if kept is not None and (inherited or kept[2].hold()):
        _GENERATED[key] = kept
        _CHECKED[key] = os.getpid()
        return kept[0], dict(kept[1])
    transforms += 1
    source, names, inputs = T.generate_with_inputs(layout, entries)
    if inputs is not None:
        _GENERATED[key] = (source, names, inputs)
        _CHECKED[key] = os.getpid()
        try:
            index.parent.mkdir(parents=True, exist_ok=True)
            tmp = index.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_text(json.dumps({"source": source, "names": names, **inputs.to_json()}))
            os.replace(tmp, index)            # atomic: another process may read it
        except OSError as err:                # a read-only cache still runs
            log.debug("soa: could not keep the generated text at %s (%s)", index, err)
    return source, names


_STEPPING: list[int] = [0]      # steps running now, each with the heap frozen


def _frozen_heap() -> bool:
    """A batch's heap as the collector sees it while a tick steps: what is
    alive (its robots, worlds, coordinators: tens of thousands of objects,
    most alive until the batch ends) is moved out of the collector's
    generations for the step (`gc.freeze`, no pass over it) and back after
    it (`_thaw`: `gc.unfreeze`, when no step in another thread still runs).
    Both are list splices, so the price is the same per step as per batch.
    Without it the first passes after a 20 x 500 batch's build went over all
    of it: 0.17-0.24 s of the collector's in a batch's 1.2-1.6 s of steps,
    0.04-0.05 s with it. Only while a step runs, not for the batch's life:
    an engine dropped unfinished inside a reference cycle (a callback that
    holds it) would stay frozen, never collected, and hold every later
    batch's heap frozen with it. Returns whether it froze (the collector
    is on); a pair of calls, not a context manager, whose generator cost a
    1,000-robot step a few per cent."""
    if not gc.isenabled():
        return False
    gc.freeze()
    _STEPPING[0] += 1
    return True


def _thaw() -> None:
    """The end of a step `_frozen_heap` froze."""
    _STEPPING[0] -= 1
    if not _STEPPING[0]:
        gc.unfreeze()


def _aged() -> None:
    """What a build made (all of it in the youngest generation, made with
    the collector off) moved to the oldest in two list splices (`gc.freeze`,
    `gc.unfreeze`, as _frozen_heap does), unless a step in another thread
    holds the heap frozen (its end moves them). Otherwise the collector's
    first pass after the build went over every object of it and found
    nothing: 50 ms of a 250-run sweep chunk's 1.1 s of CPU."""
    gc.freeze()
    if not _STEPPING[0]:
        gc.unfreeze()


def _nfields() -> list[int]:
    top = max(msg.SCHEMA) + 1
    return [len(msg.fields(k)) if k in msg.SCHEMA else 0 for k in range(top)]


def _small_ints(values: list[int], dtype: np.dtype) -> Any:
    """`values` to assign to an array of `dtype`: as bytes when every one is
    0..127 (0..255 beyond int8), which a grid's cell codes and robot counts
    mostly are (a C loop, a third of a list's conversion), else the list
    itself (numpy converts it, and refuses a value the dtype cannot hold)."""
    try:
        raw = bytes(values)
    except (ValueError, TypeError):          # negative, past 255, or not an int
        return values
    if dtype.itemsize == 1 and not raw.isascii():
        return values
    return np.frombuffer(raw, dtype=np.uint8)


class BatchArrays:
    """The flat arrays of a batch of worlds (sim_backend/batch/body.py's
    layout), filled from each World's start: the kernel's world state of
    every run (kernel.Grid, Robots, Run); what a BatchBody is made of."""

    def __init__(self, worlds: Sequence[World]) -> None:
        nr = len(worlds)
        agents = [len(w.xs) for w in worlds]
        self.starts = np.concatenate([[0], np.cumsum(agents)]).astype(np.int64)
        starts = self.starts
        nrob = int(starts[-1])
        self.stride = max(w.n * w.n for w in worlds)
        tables = [(w.tdx, w.tdy, w.tv) for w in worlds]
        tstarts = np.concatenate([[0], np.cumsum([len(t[0]) for t in tables])])
        cells = [w.cell_arrays() for w in worlds]
        cstarts = np.concatenate([[0], np.cumsum([len(c[0]) for c in cells])])
        # every run's row of each kernel.RUN_FIELDS name, its World's own value
        # but for where its share of the batch's arrays starts and ends
        rt = np.array([[getattr(w.run, name)[0] for w in worlds]
                       for name in kernel.RUN_FIELDS], dtype=np.int64).reshape(B.RUN_ROWS, nr)
        for r in range(nr):
            run = dict(base=r * self.stride, lo=starts[r], hi=starts[r + 1], t0=tstarts[r],
                       t1=tstarts[r + 1], c0=cstarts[r], c1=cstarts[r + 1])
            for name, v in run.items():
                rt[kernel.RUN_FIELDS.index(name), r] = v
        table = np.zeros((3, max(1, int(tstarts[-1]))), dtype=np.int64)
        cell = np.zeros((4, max(1, int(cstarts[-1]))), dtype=np.int64)
        if max(agents) > np.iinfo(B.GRID_TYPES[B.OCC]).max:
            raise EngineError(f"{max(agents)} robots in one run overflow the batch "
                              f"engine's occupancy grid ({B.GRID_TYPES[B.OCC]})")
        grids = tuple(np.zeros(nr * self.stride, dtype=t) for t in B.GRID_TYPES)
        grids[B.STAMP][:] = -1
        rb = np.zeros((B.ROBOT_ROWS, nrob), dtype=np.int64)
        # a grid (or signal table) equal to the run before's is copied from
        # its array: a sweep's runs mostly start on the same object, owner and
        # field grids and one table, and a list's conversion costs far more
        # than comparing it
        last: dict[int, tuple[list, int]] = {}
        prev_table: tuple[tuple[list, ...], int, int] | None = None
        for r, w in enumerate(worlds):
            a, b = int(tstarts[r]), int(tstarts[r + 1])
            if prev_table is not None and prev_table[0] == tables[r]:
                table[:, a:b] = table[:, prev_table[1]:prev_table[2]]
            else:
                table[:, a:b] = tables[r]
            prev_table = (tables[r], a, b)
            a, b = int(cstarts[r]), int(cstarts[r + 1])
            cell[:2, a:b] = cells[r][:2]
            base, size = r * self.stride, w.n * w.n
            for row, grid in ((B.OBJ, w.obj), (B.OWNER, w.owner), (B.FIELD, w.field),
                              (B.OCC, w.occ)):
                prev = last.get(row)
                if prev is not None and len(prev[0]) == size and prev[0] == grid:
                    grids[row][base:base + size] = grids[row][prev[1]:prev[1] + size]
                else:
                    grids[row][base:base + size] = _small_ints(grid, grids[row].dtype)
                last[row] = (grid, base)
        # each robot field of every run in one conversion (the runs' robots
        # are consecutive)
        for j, name in enumerate(kernel.ROBOT_FIELDS):
            rb[j, :] = np.fromiter(chain.from_iterable(getattr(w.rb, name) for w in worlds),
                                   np.int64, nrob)
        rb[B.RUN, :] = np.repeat(np.arange(nr, dtype=np.int64), agents)
        self.rt, self.rb, self.grids, self.cells, self.table = rt, rb, grids, cell, table
        self.grid = kernel.Grid(grids, table, cell)
        self.robots = kernel.Robots(rb)
        self.runs = kernel.Run(rt)
        cap = SENDS_PER_ROBOT * nrob + 16
        self.out_i = np.zeros(cap, dtype=np.int64)
        self.out_kind = np.zeros(cap, dtype=np.int64)
        self.out_f = np.zeros((cap, B.FIELDS), dtype=np.int64)
        self.out_n = np.zeros(2, dtype=np.int64)
        self.in_kind = np.zeros((nrob, INBOX), dtype=np.int64)
        self.in_nf = np.zeros((nrob, INBOX), dtype=np.int64)
        self.in_f = np.zeros((nrob, INBOX, B.FIELDS), dtype=np.int64)

    def body_args(self) -> tuple:
        """BatchBody's constructor arguments (the arrays are shared, not copied)."""
        return (self.grid, self.robots, self.runs, self.rb, self.out_i, self.out_kind,
                self.out_f, self.out_n, self.in_kind, self.in_nf, self.in_f)


class SoaEngine:
    """A batch of independent runs (scenario, seed) of one behaviour."""

    compile_seconds = 0.0            # this process's, all SoaEngines together
    _soonest = 0                     # no wake tick is before it (_exchange)

    def __init__(self, runs: Sequence[tuple[Scenario, int]], record_trajectories: bool = False,
                 until: str = "delivered", grids: bool = True) -> None:
        """`grids`: a finished run's World gets its grids back (obj, owner,
        field, occ, stamp); without, they stay as the run began, which only
        a caller that reads none of them may ask (run_batch: a summary reads
        the robots' places and the object's cells, no grid)."""
        if until not in UNTIL:
            raise ValueError(f"until: expected one of {UNTIL}, got {until!r}")
        self.runs = list(runs)
        if not self.runs:
            raise EngineError("a batch needs at least one run")
        names = {sc.behaviour for sc, _ in self.runs}
        if len(names) != 1:
            raise EngineError(f"a batch runs one behaviour, got {sorted(map(str, names))}")
        self.behaviour = registry.load(names.pop()).activate()   # its message kinds in use
        self.declared = declared_measures(self.behaviour.spec)
        self.until = until
        self.record = record_trajectories
        self.grids_back = grids
        self.tick = 0
        self.nfields = _nfields()
        t0 = time.perf_counter()
        # a batch's build makes tens of thousands of objects and no garbage
        # cycle: the collector, run every few hundred of them, found nothing
        # and cost a quarter of the build
        collecting = gc.isenabled()
        gc.disable()
        try:
            self._build()
        finally:
            if collecting:
                _aged()
                gc.enable()
        self.setup_seconds = time.perf_counter() - t0

    # -- set-up -------------------------------------------------------------------------

    def _build(self) -> None:
        runs = self.runs
        nr = len(runs)
        self.worlds = [World(sc, seed) for sc, seed in runs]
        arrays = BatchArrays(self.worlds)
        self.stride = arrays.stride
        self.rt, self.rb, self.grids, self.cells = arrays.rt, arrays.rb, arrays.grids, arrays.cells
        self.out_i, self.out_kind, self.out_f, self.out_n = \
            arrays.out_i, arrays.out_kind, arrays.out_f, arrays.out_n
        self.in_kind, self.in_nf, self.in_f = arrays.in_kind, arrays.in_nf, arrays.in_f
        args = arrays.body_args()
        starts = arrays.starts
        rb = self.rb

        self._compile(args)
        beh = self.behaviour
        from perception import host_coordinator
        self.coords = [host_coordinator(beh, sc, cells=list(w.object_cells))
                       for (sc, _), w in zip(runs, self.worlds)]
        self.wake = np.array([wake(c) for c in self.coords], dtype=np.int64)
        self.lo = starts[:-1].tolist()
        self.agents = np.diff(starts).tolist()
        self.run_of = rb[B.RUN].tolist()
        self.node_of = (np.arange(len(self.run_of)) - starts[rb[B.RUN]] + 1).tolist()
        # what each coordinator declared muted at its last tick
        self.mutes = BatchMutes(self.coords, self.lo, self.agents, rb[B.RUN])
        self.max_ticks = np.array([sc.maxTicks for sc, _ in runs], dtype=np.int64)
        self.first_cap = int(self.max_ticks.min())    # no run ends at its cap before
        self.conv_steps = [-1] * nr      # rt[STEPS] when the run converged
        self.results: list[RunResult | None] = [None] * nr
        # runs not live: counted as _finish ends them, so that run() reads
        # neither the live row nor a sum of it on each of a batch's ticks
        self.ended = int((self.rt[B.LIVE] != 1).sum())
        self.frames: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._step_once_compiled = False

    def _compile(self, args: tuple) -> None:
        """The robots (built by their CPython constructors) and the body as
        arrays, and the compiled step (generated, or found in this process)."""
        c0 = time.perf_counter()
        beh = self.behaviour
        self.robot_objs = [beh.make_robot(node, seed, sc)
                           for sc, seed in self.runs for node in range(1, sc.agents + 1)]
        self.body_obj = B.BatchBody(*args)
        self.layout, self.compiled, self.arrays = compile_batch(self.robot_objs, self.body_obj)
        tick_all, names = self.compiled.entry("tick_all")
        self._tick_fn, self._tick_args = tick_all, tuple(self.arrays[n] for n in names)
        states_of, names = self.compiled.entry("states_of")
        self._states_fn, self._states_args = states_of, tuple(self.arrays[n] for n in names)
        SoaEngine.compile_seconds += time.perf_counter() - c0

    def _tick(self, t: int) -> None:
        self._tick_fn(*self._tick_args, 0, t)

    def _states(self, out: np.ndarray) -> None:
        self._states_fn(*self._states_args, out)

    def _first_tick(self, t: int) -> None:
        """The first tick: the calls that load the step from the disk cache,
        or compile it."""
        self.compiled.first_call(self._tick_fn, self._tick_args + (0, t), "tick_all")
        self._exchange_entries()
        if self.record:
            out = np.zeros(len(self.robot_objs), dtype=np.int64)
            self.compiled.first_call(self._states_fn, self._states_args + (out,), "states_of")

    # the exchange's halves (body.py `sift`, `deliver`) run as Python until
    # the first tick loads them compiled (`_exchange_entries`): an engine
    # built and not stepped delivers as a stepped one does
    _sift_fn: Callable[..., int] = staticmethod(B.sift)
    _deliver_fn: Callable[..., int] = staticmethod(B.deliver)

    @cached_property
    def _sift_args(self) -> tuple:
        """`sift`'s arrays: the outbox, the mutes (exchange.BatchMutes), the
        kept messages' rows and the ended clauses' senders it writes."""
        mutes = self.mutes
        self._kept = np.zeros((len(self.out_i), 3 + B.FIELDS), dtype=np.int64)
        self._ended = np.zeros(len(self.runs) + 1, dtype=np.int64)
        return (self.out_i, self.out_kind, self.out_f, B.FIELDS, mutes.muted, mutes.repeats,
                mutes.same, mutes.same_n, mutes.run_of, self._kept, self._ended)

    @cached_property
    def _deliver_args(self) -> tuple:
        """`deliver`'s arrays: the inbox rings."""
        return (self.in_kind, self.in_nf, self.in_f, self.rb[B.IN_HEAD], self.rb[B.IN_TAIL],
                INBOX)

    def _exchange_entries(self) -> None:
        """The exchange's halves compiled, loaded or compiled by a first
        call that changes nothing."""
        self._sift_fn = self.compiled.entry("sift")[0]
        self._deliver_fn = self.compiled.entry("deliver")[0]
        none = np.zeros(3, dtype=np.int64)
        self.compiled.first_call(self._sift_fn, self._sift_args + (0,), "sift")
        self.compiled.first_call(self._deliver_fn, self._deliver_args + (none, none, 0),
                                 "deliver")

    # -- one tick ---------------------------------------------------------------------------

    def step(self) -> None:
        if not _frozen_heap():
            self._step()
            return
        try:
            self._step()
        finally:
            _thaw()

    def _step(self) -> None:
        self.tick += 1
        t = self.tick
        try:
            if not self._step_once_compiled:
                c0 = time.perf_counter()
                self._first_tick(t)
                SoaEngine.compile_seconds += time.perf_counter() - c0
                self._step_once_compiled = True
            else:
                self._tick(t)
        except OverflowError as e:
            # borrow.fits: a behaviour's int left the int32 the tables hold
            # (a firmware int lives in 31 bits); the compiled step cannot
            # say which field, the reference engine runs the same code
            raise EngineError(f"tick {t}: a behaviour's field left the firmware int range "
                              f"({e}): an int the firmware subset does not hold (|x| < 2**30 on a "
                              "32-bit board)") from None
        if self.out_n[1]:
            raise EngineError(f"tick {t}: a robot sent more than {SENDS_PER_ROBOT} messages "
                              "in one tick (the batch engine's outbox is full)")
        if self.record:
            st = np.zeros(len(self.robot_objs), dtype=np.int64)
            self._states(st)
            self.frames.append((self.rb[B.XS].copy(), self.rb[B.YS].copy(), st))
        self._finish(t, self._exchange(t))

    def _exchange(self, t: int) -> list[int]:
        """This tick's messages to their coordinators in the order they were
        sent and a tick of every coordinator that heard one or whose wake
        tick came (in run order; sim_backend/exchange.py); their commands reach the
        robots' inboxes together. Returns the runs whose coordinator ended
        them (run_ended), in run order.

        The work is per message and per coordinator asked, not per run of
        the batch: a sweep's batch steps on for hundreds of ticks with a
        few runs live, and a pass over every run's wake tick each step cost
        as much as the live runs' exchange. `_soonest` is a lower bound of
        every wake tick (a finished run's is NEVER), so the wake ticks are
        read only on a step that may find one due."""
        n = int(self.out_n[0])
        ups: dict[int, list[tuple[int, int, tuple]]] = {}
        mutes = self.mutes
        if n:
            k = self._sift_fn(*self._sift_args, n)
            if self._ended[0]:
                mutes.end(self._ended)
            run_of, node_of, nfields = self.run_of, self.node_of, self.nfields
            for row in self._kept[:k].tolist():
                i, kind = row[1], row[2]
                r = run_of[i]
                up = ups.get(r)
                if up is None:
                    up = ups[r] = []
                up.append((node_of[i], kind, tuple(row[3:3 + nfields[kind]])))
        woken = self.wake
        due = t >= self._soonest
        # numpy's calls cost a few microseconds each whatever the length: a
        # batch of few runs (a 1,000-robot run, due on each transport tick)
        # reads its wake ticks as a list
        few = due and len(woken) <= _FEW_RUNS
        if not due:
            asked = set()
        elif few:
            asked = {r for r, w in enumerate(woken.tolist()) if w <= t}
        else:
            asked = set(np.flatnonzero(woken <= t).tolist())
        soonest = NEVER if due else self._soonest
        coords, conv, until = self.coords, self.conv_steps, self.until
        update = mutes.update
        ended: list[int] = []
        sends = []
        # `sift` dropped the muted messages (HEARS_ALL here), and a run here
        # heard one or was asked, so each is ticked
        for r in sorted(asked.union(ups)) if asked else sorted(ups):
            c = coords[r]
            out = exchange(c, ups.get(r, ()), t, True, HEARS_ALL)
            if out:
                sends.append((r, out))
            w = wake(c)
            woken[r] = w
            if w < soonest:
                soonest = w
            update(r, c)
            if conv[r] < 0 and c.converged_tick >= 0:
                conv[r] = int(self.rt[B.STEPS, r])
            if run_ended(c, until):
                ended.append(r)
        # a step that read the wake ticks knows their least exactly
        if few:
            self._soonest = min(woken.tolist())
        else:
            self._soonest = int(woken.min()) if due else soonest
        if sends:
            self._deliver(sends)
        return ended

    def _deliver(self, sends: Sequence[tuple[int, Iterable[tuple[int, int, tuple]]]]) -> None:
        """Commands (run, [(node, kind, fields), ...]) into the robots'
        inbox rings, each robot's in the order given, by one compiled call
        (body.py `deliver`) over spans of robots (first, count, row): a
        command is one robot's span, a HALT to HOST its run's. A tick
        delivers tens of commands (a transport step's to each holder, one
        fields object for all) to thousands (a HALT to every robot of a
        run, the first tick's ACK to every robot): each distinct (kind,
        fields) is checked and padded to a whole row once and a message
        names that row's number, so the loop over messages only appends
        (the robot reads a row's first `in_nf` fields only, body.py `recv`)."""
        todo: list[int] = []
        rows: dict[tuple[int, tuple], int] = {}   # (kind, fields) -> row number
        table: list[int] = []                      # rows of kind, nf, padded fields
        pad = _PAD
        lo_of, agents_of = self.lo, self.agents
        host = msg.HOST                  # 0: never a robot's node
        last_f, last_kind, k = None, -1, 0
        span, row_of = todo.extend, table.extend
        for r, out in sends:
            lo, agents = lo_of[r], agents_of[r]
            base = lo - 1                # node n is robot base + n
            for node, kind, f in out:
                # a run's commands to its holders share one fields object:
                # its row is the last one's, without hashing the key again
                if f is not last_f or kind != last_kind:
                    last_f, last_kind = f, kind
                    key = (kind, f)
                    try:
                        row = rows.get(key)
                    except TypeError:            # fields as a list
                        key = (kind, tuple(f))
                        row = rows.get(key)
                    if row is None:
                        nf = len(f)
                        if nf > B.FIELDS:
                            raise EngineError(f"run {r}: the coordinator sent {nf} fields, "
                                              f"more than a message holds ({B.FIELDS})")
                        row = rows[key] = len(rows)
                        row_of((kind, nf))
                        row_of(f)
                        row_of(pad[nf])
                    k = row
                if 1 <= node <= agents:
                    span((base + node, 1, k))
                elif node == host:
                    span((lo, agents, k))
                else:
                    raise EngineError(f"run {r}: the coordinator addressed node {node}, "
                                      f"which is not one of its {agents} robots")
        if not todo:
            return
        i = self._deliver_fn(*self._deliver_args, np.array(todo, dtype=np.int64),
                             np.array(table, dtype=np.int64), len(todo) // 3)
        if i >= 0:
            r = self.run_of[i]
            raise EngineError(f"run {r}: robot {i - self.lo[r] + 1} has {INBOX} unread messages")

    # -- run ends -----------------------------------------------------------------------------

    def _finish(self, t: int, ended: list[int]) -> None:
        """The runs that ended this tick (`ended`, run order), and from the
        first maxTicks on those at their cap, into their results."""
        live = self.rt[B.LIVE]
        done: Iterable[int] = ended
        if t >= self.first_cap:
            capped = np.flatnonzero((live == 1) & (self.max_ticks <= t)).tolist()
            if capped:
                done = sorted(set(ended).union(capped))
        for r in done:
            if live[r] == 1:
                self._result(r, t)
                live[r] = 0
                self.ended += 1
                self.wake[r] = NEVER     # never asked again

    def _result(self, r: int, t: int) -> None:
        """The run's final state into its World and, when its RunResult's
        robots are first read, its robots back into their CPython objects,
        as the reference engine leaves them. Late is the same: a finished
        run is never ticked again (an instance its robots shared with a live
        run's would be read as it is then; no behaviour's robots share one).
        Each row is read as a slice of its own type: a grid's list costs per
        cell (nine tenths of this), and widening it first, or taking the
        runs that ended in one tick in one fancy index, costs more."""
        sc, seed = self.runs[r]
        w = self.worlds[r]
        lo, hi, c0, c1 = self.rt[_BOUNDS, r].tolist()
        objs = self.robot_objs[lo:hi]
        base, size = r * self.stride, w.n * w.n
        for row, name in _WORLD_GRIDS if self.grids_back else ():
            # in place: the World's Grid holds these lists
            getattr(w, name)[:] = self.grids[row][base:base + size].tolist()
        w.xs[:], w.ys[:], w.held[:] = self.rb[_ROBOT_ROWS, lo:hi].tolist()
        w.object_cells = list(zip(*self.cells[:2, c0:c1].tolist()))
        traj, states = [], []
        for xs, ys, st in self.frames[:t]:
            traj.append((xs[lo:hi].tolist(), ys[lo:hi].tolist()))
            states.append(st[lo:hi].tolist())
        res = RunResult(sc, seed, t, w, self.coords[r], objs, traj, conv_steps=self.conv_steps[r],
                        fill=partial(T.unpack, self.layout, self.arrays, objs),
                        declared=self.declared)
        res.states = states
        self.results[r] = res

    # -- a whole batch ----------------------------------------------------------------------------

    def finished(self) -> bool:
        return not bool(self.rt[B.LIVE].any())

    def run(self, progress: Callable[[int], None] | None = None) -> list[RunResult]:
        nr = len(self.runs)
        while self.ended < nr:
            self.step()
            if progress is not None:
                progress(self.ended)
        return list(self.results)  # type: ignore[arg-type]


def _pairs(scenarios: Scenario | Sequence[Scenario], seeds: Iterable[int]
           ) -> list[tuple[Scenario, int]]:
    if isinstance(scenarios, Scenario):
        return [(scenarios, int(s)) for s in seeds]
    scs = list(scenarios)
    sds = list(seeds)
    if len(scs) != len(sds):
        raise ValueError("run_batch: a list of scenarios needs one seed per scenario")
    return [(sc, int(s)) for sc, s in zip(scs, sds)]


def run_batch_results(scenarios: Scenario | Sequence[Scenario], seeds: Iterable[int],
                      record_trajectories: bool = False, until: str = "delivered",
                      progress: Callable[[int], None] | None = None,
                      grids: bool = True) -> list[RunResult]:
    """RunResults in input order: one scenario for every seed, or one scenario
    per seed; runs of different behaviours go in one batch each (`grids`:
    SoaEngine's)."""
    pairs = _pairs(scenarios, seeds)
    groups: dict[str, list[int]] = defaultdict(list)
    for j, (sc, _) in enumerate(pairs):
        groups[str(sc.behaviour)].append(j)
    out: list[RunResult | None] = [None] * len(pairs)
    done = 0
    for idx in groups.values():
        eng = SoaEngine([pairs[j] for j in idx], record_trajectories=record_trajectories,
                        until=until, grids=grids)
        base = done
        res = eng.run(None if progress is None else (lambda k: progress(base + k)))
        for j, rr in zip(idx, res):
            out[j] = rr
        done += len(idx)
    return out  # type: ignore[return-value]


def run_batch(scenarios: Scenario | Sequence[Scenario], seeds: Iterable[int],
              trajectories: bool = False, until: str = "delivered",
              progress: Callable[[int], None] | None = None):
    """Summaries identical to RunResult.summary() of the reference engine.

    With trajectories=True returns (summaries, trajectories), each trajectory a
    list per tick of (xs, ys) as Engine(record_trajectories=True) records it.
    """
    # the results go once summarised: their worlds' grids, nine tenths of a
    # finished run's conversion, are not read (a summary reads no grid)
    res = run_batch_results(scenarios, seeds, record_trajectories=trajectories, until=until,
                            progress=progress, grids=False)
    # perception's end fields of the batch at once: its recognitions share
    # numpy calls (two thirds of a sweep's summaries went to them one by one)
    from perception.tracker import end_fields_all
    bare = [r for r in res if not r.instruments]
    for r, end in zip(bare, end_fields_all(bare)):
        r.end = end
    sums = [r.summary() for r in res]
    if trajectories:
        return sums, [r.trajectories for r in res]
    return sums


def _first_engines(scenarios: Iterable[Any]) -> dict[str, "SoaEngine"]:
    """One one-run, one-tick engine per behaviour of `scenarios` (built, not
    stepped: its transform is generated and written, nothing compiles)."""
    first: dict[str, Any] = {}
    for sc in scenarios:
        first.setdefault(str(sc.behaviour), sc)
    return {name: SoaEngine([(sc.replace(maxTicks=1), 1)]) for name, sc in first.items()}


def cold(scenarios: Iterable[Any]) -> dict[str, Path]:
    """The behaviours of `scenarios` whose step the disk cache does not hold
    yet, each with its cache folder; nothing compiles (about 0.2 s of
    transform per behaviour)."""
    return {name: eng.compiled.path.parent
            for name, eng in _first_engines(scenarios).items()
            if not eng.compiled.on_disk("tick_all")}


def warm(scenarios: Iterable[Any], on_compile: Callable[[str, Path], None] | None = None
         ) -> list[str]:
    """Compile, or load from the disk cache, the step of every behaviour of
    `scenarios` in this process (one run of one tick each); on_compile(behaviour,
    cache folder) is called before a compile the cache does not hold. Returns
    the behaviours that compiled."""
    built = []
    for name, eng in _first_engines(scenarios).items():
        if not eng.compiled.on_disk("tick_all"):
            built.append(name)
            log.info("compiling the soa engine for behaviour %s (cache %s)", name,
                     eng.compiled.path.parent)
            if on_compile is not None:
                on_compile(name, eng.compiled.path.parent)
        eng.step()
    return built
