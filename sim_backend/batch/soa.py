"""The struct-of-arrays batch engine: the batch engine's runs, robots and
rules, with the firmware source transformed into array functions
(sim_backend/batch/transform.py) instead of jitclasses.

The robots are built by their CPython constructors, packed into one array
per field, and stepped by `tick_all` of sim_backend/batch/body.py,
transformed along with every method and function it reaches. The generated
module is written to a cache directory keyed by a hash of its own text
(`$TOUCHSWARM_CACHE` or `~/.cache/touchswarm`, then `soa/<hash>/`) and
compiled with `njit(cache=True)`: a second process with the same sources
loads the machine code from disk instead of compiling it. A changed
behaviour source is a different text, so a different directory.

At a run's end the robots' fields are written back into their CPython
objects, so a RunResult holds the very robots the reference engine holds.
"""

from __future__ import annotations

import hashlib
import importlib.util
import logging
import os
import shutil
import sys
import threading
import time
import traceback
from pathlib import Path
from types import ModuleType
from typing import Any, Callable, Iterable

import numpy as np

from sim_backend.batch import body as B
from sim_backend.batch import transform as T
from sim_backend.batch.engine import BatchEngine

log = logging.getLogger(__name__)

PREFIX = "_touchswarm_soa_"


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
            spec = importlib.util.spec_from_file_location(name, path)
            assert spec is not None and spec.loader is not None
            mod = importlib.util.module_from_spec(spec)
            sys.modules[name] = mod          # numba pickles State by module name
            spec.loader.exec_module(mod)
            self.module = mod
            log.debug("soa module %s at %s", name, path)
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

    def first_call(self, fn: Any, args: tuple) -> Any:
        """fn(*args), the call that compiles fn or loads it from the disk
        cache. numba raises on a cache file it cannot unpickle (a truncated
        or damaged index or data file) instead of compiling again; then the
        module's cache is deleted, a warning names it, and fn compiles."""
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
    for r in robots:
        layout.add(r)
    rcls = type(robots[0])
    body_cls = type(body)
    entries = {"tick_all": (B.tick_all, (T.ListOf(rcls), T.Inst(body_cls), T.SCALAR)),
               "states_of": (B.states_of, (T.ListOf(rcls), T.SCALAR))}
    source, names = T.generate(layout, entries)
    key = hashlib.sha256(source.encode()).hexdigest()
    comp = _LOADED.get(key)
    if comp is None:
        comp = _LOADED[key] = Compiled(source, names)
    return layout, comp, T.state_arrays(layout)


class SoaEngine(BatchEngine):
    """BatchEngine with the struct-of-arrays transform in place of jitclasses."""

    compile_seconds = 0.0            # this process's, all SoaEngines together

    def _compile(self, args: tuple) -> None:
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
        # the calls that load the step from the disk cache, or compile it
        self.compiled.first_call(self._tick_fn, self._tick_args + (0, t))
        if self.record:
            out = np.zeros(len(self.robot_objs), dtype=np.int64)
            self.compiled.first_call(self._states_fn, self._states_args + (out,))

    def _note_compile(self, seconds: float) -> None:
        SoaEngine.compile_seconds += seconds

    def _result(self, r: int, t: int) -> None:
        lo, hi = int(self.rt[B.LO, r]), int(self.rt[B.HI, r])
        for robot in self.robot_objs[lo:hi]:
            T.unpack(self.layout, self.arrays, robot)
        super()._result(r, t)


def warm(scenarios: Iterable[Any], on_compile: Callable[[str, Path], None] | None = None
         ) -> list[str]:
    """Compile, or load from the disk cache, the step of every behaviour of
    `scenarios` in this process (one run of one tick each); on_compile(behaviour,
    cache folder) is called before a compile the cache does not hold. Returns
    the behaviours that compiled."""
    first: dict[str, Any] = {}
    for sc in scenarios:
        first.setdefault(str(sc.behaviour), sc)
    cold = []
    for name, sc in first.items():
        eng = SoaEngine([(sc.replace(maxTicks=1), 1)])
        if not eng.compiled.on_disk("tick_all"):
            cold.append(name)
            log.info("compiling the soa engine for behaviour %s (cache %s)", name,
                     eng.compiled.path.parent)
            if on_compile is not None:
                on_compile(name, eng.compiled.path.parent)
        eng.step()
    return cold
