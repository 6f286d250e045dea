"""Compile unmodified firmware-subset modules with numba.

Each module's own source is executed again into a *twin* module whose
imports resolve to twins too; then every function of a twin becomes a numba
`njit` dispatcher and every class a `jitclass` whose field types are read off
a live CPython instance (ints -> int64, lists of ints -> a numba list,
instances of twinned classes -> their jitclass). Nothing is transformed or
copied by hand: a change to a behaviour's source is a change to the compiled
engine (tests/test_batch_engine.py proves it on a mutated copy).

The CPython modules stay untouched, so the reference engine, the board and
MicroPython keep running the very same files.
"""

from __future__ import annotations

import builtins
import importlib
import logging
import sys
import time
from pathlib import Path
from types import FunctionType, ModuleType
from typing import Any

import numpy as np

from sim_backend.errors import EngineError

log = logging.getLogger(__name__)

_PASS_THROUGH = ("__future__",)
TWIN_PREFIX = "_touchswarm_twin"


class CompileError(EngineError):
    """A module the batch engine cannot compile (a construct outside the subset)."""


class Twins:
    """One set of compiled twins; every engine of a process shares it."""

    def __init__(self) -> None:
        import numba  # the compiler is needed only here: a warm `touchswarm run` never loads it
        self.numba = numba
        self.by_file: dict[str, ModuleType] = {}
        self.classes: dict[tuple[str, str], Any] = {}    # (file, class name) -> jitclass
        self.compile_seconds = 0.0
        self._builtins = dict(vars(builtins))
        self._builtins["__import__"] = self._import

    # -- twin modules --------------------------------------------------------------

    def module(self, real: ModuleType) -> ModuleType:
        """The twin of an imported CPython module (compiled lazily, once)."""
        path = getattr(real, "__file__", None)
        if not path:
            raise CompileError(f"module {real.__name__} has no source file to compile")
        key = str(Path(path).resolve())
        if key in self.by_file:
            return self.by_file[key]
        # a twin is importable under its own name: numba pickles compiled
        # types by reference (module + qualified name) when it boxes them
        twin = ModuleType(f"{TWIN_PREFIX}{len(self.by_file)}_{real.__name__.replace('.', '_')}")
        sys.modules[twin.__name__] = twin
        twin.__file__ = path
        ns = twin.__dict__
        ns["__builtins__"] = self._builtins
        if hasattr(real, "__path__"):
            twin.__path__ = list(real.__path__)
        self.by_file[key] = twin
        source = Path(path).read_text()
        exec(compile(source, path, "exec"), ns)           # noqa: S102 (our own source)
        for name, value in list(ns.items()):
            if isinstance(value, FunctionType) and value.__module__ == twin.__name__:
                ns[name] = self.numba.njit(value)
        log.debug("twinned %s", real.__name__)
        return twin

    def _import(self, name, globals=None, locals=None, fromlist=(), level=0):
        if level != 0:
            raise CompileError(f"relative import of {name!r}: the firmware subset "
                               "imports absolutely")
        if name.split(".")[0] in _PASS_THROUGH:
            return importlib.__import__(name, globals, locals, fromlist, level)
        real = importlib.import_module(name)
        if fromlist:
            twin = self.module(real)
            for item in fromlist:
                sub = f"{name}.{item}"
                if not hasattr(real, item) or isinstance(getattr(real, item), ModuleType):
                    setattr(twin, item, self.module(importlib.import_module(sub)))
            return twin
        # `import a.b` binds `a`: give a stand-in whose attributes lead to twins
        top = ModuleType(name.split(".")[0])
        parts = name.split(".")
        here = top
        for j in range(1, len(parts)):
            mod = importlib.import_module(".".join(parts[: j + 1]))
            nxt = self.module(mod) if j == len(parts) - 1 else ModuleType(parts[j])
            setattr(here, parts[j], nxt)
            here = nxt
        return top

    # -- classes ---------------------------------------------------------------------

    def jitclass_of(self, sample: Any) -> Any:
        """The jitclass compiled from the class of `sample`, a CPython instance
        whose attributes give the field types."""
        cls = type(sample)
        real_mod = importlib.import_module(cls.__module__)
        twin = self.module(real_mod)
        key = (twin.__file__, cls.__name__)
        if key in self.classes:
            return self.classes[key]
        spec = []
        for attr, value in vars(sample).items():
            spec.append((attr, self._field_type(cls, attr, value)))
        twin_cls = twin.__dict__.get(cls.__name__)
        if not isinstance(twin_cls, type):
            raise CompileError(f"{cls.__module__}.{cls.__name__} is not a class of its module")
        jc = self.numba.experimental.jitclass(spec)(twin_cls)
        self.classes[key] = jc
        # every twin that imported the plain class now sees the compiled one
        for mod in self.by_file.values():
            for name, value in list(vars(mod).items()):
                if value is twin_cls:
                    setattr(mod, name, jc)
        return jc

    def _field_type(self, cls: type, attr: str, value: Any) -> Any:
        t = self.numba.types
        if isinstance(value, bool):
            return t.boolean
        if isinstance(value, int):
            return t.int64
        if isinstance(value, list) and all(type(v) is int for v in value):
            return t.List(t.int64, reflected=False)
        if isinstance(value, np.ndarray):
            return self.numba.typeof(value)
        if type(value).__module__ in ("builtins", "numpy"):
            raise CompileError(f"{cls.__name__}.{attr}: a {type(value).__name__} is outside "
                               "the subset the batch engine compiles (ints, lists of ints, "
                               "objects of such classes)")
        return self.jitclass_of(value).class_type.instance_type

    def function(self, real_function: FunctionType) -> Any:
        """The compiled twin of a module-level function."""
        twin = self.module(importlib.import_module(real_function.__module__))
        return getattr(twin, real_function.__name__)


_TWINS: Twins | None = None


def twins() -> Twins:
    """The process's compiled twins (numba's jitclasses cannot be cached on disk,
    so each process compiles once, on first use)."""
    global _TWINS
    if _TWINS is None:
        t0 = time.perf_counter()
        _TWINS = Twins()
        _TWINS.compile_seconds += time.perf_counter() - t0
    return _TWINS
