"""Behaviours by name or by folder: the one seam every engine, link and tool
goes through: host code, CPython only, so it lives beside the engine and not
in firmware_logic/ (which holds only what may run on a robot).

A behaviour is a package of firmware-subset modules:

    spec.py         its declaration: NAME, TITLE, STATES, MODELS,
                    PARAMS, MEASURES (see behaviours/thesis/spec.py), and
                    optionally REPORTERS ((name, meaning), ...: values its
                    coordinator's reporters() gives at every tick) and MESSAGES, its own message kinds in the
                    format of messages.MESSAGES (kinds messages.FREE_KINDS, checked
                    at load; per behaviour: Behaviour.activate() puts them in use)
    robot.py        the FSM class named by ROBOT, stepped as `robot.step(hal)`
    coordinator.py  its host-side coordinator (portable, may allocate)
    studies.py      optional: STUDIES, named sweeps and their figures as data
                    (sim_backend/studies.py; `touchswarm sweep --study NAME`)
    __init__.py     the wiring: ROBOT = "module:Class", and
                    robot_args(node, seed, sc) -> the FSM's constructor args,
                    make_coordinator(sc) -> its coordinator for a scenario

Found by name among the built-ins (every package in firmware_logic/behaviours/) and the entry points of the group
`touchswarm.behaviours` (a separately installed package adds one with
`[project.entry-points."touchswarm.behaviours"] mine = "my_pkg.mine"`), or
by path to a folder holding such a package.
"""

from __future__ import annotations

import functools
import importlib
import importlib.util
import os
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

import firmware_logic.behaviours
from sim_backend.errors import SimError

GROUP = "touchswarm.behaviours"
BEHAVIOURS_DIR = Path(firmware_logic.behaviours.__file__).resolve().parent
BUILTIN_PREFIX = "firmware_logic.behaviours."
SPEC_KEYS = ("NAME", "TITLE", "STATES", "MODELS", "PARAMS", "MEASURES")


class BehaviourError(SimError, ValueError):
    """A behaviour that cannot be found or does not declare what it must."""


@dataclass(frozen=True)
class Behaviour:
    name: str
    package: ModuleType
    spec: ModuleType

    @property
    def module_name(self) -> str:
        return self.package.__name__

    @property
    def folder(self) -> Path:
        init = self.package.__file__
        if init is None:        # a namespace package: no __init__.py to wire it
            raise BehaviourError(f"behaviour {self.name!r}: its package has no __init__.py")
        return Path(init).resolve().parent

    # robot_module and robot_class are per behaviour, not per robot: looked
    # up once per Behaviour (an engine builds one robot per node through them)
    @functools.cached_property
    def robot_module(self) -> ModuleType:
        try:
            return importlib.import_module(self.module_name + "."
                                           + self.package.ROBOT.split(":")[0])
        except Exception as err:      # noqa: BLE001 - the user's file, one line
            raise code_error(repr(self.name), self.folder, err) from err

    @functools.cached_property
    def robot_class(self) -> type:
        return getattr(self.robot_module, self.package.ROBOT.split(":")[1])

    @property
    def ref(self) -> str:
        """How a scenario names this behaviour: its installed name, or its folder."""
        return self.name if module_of(self.name) == self.module_name else str(self.folder)

    def robot_args(self, node: int, seed: int, sc: Any) -> tuple:
        """The FSM's constructor arguments for robot `node`, read off the
        scenario of its breed (a [[breeds]] table may set any parameter);
        BehaviourError when their number does not fit the constructor."""
        if getattr(sc, "breeds", ()):
            sc = sc.for_node(node)
        try:
            args = tuple(self.package.robot_args(node, seed, sc))
        except SimError:
            raise
        except Exception as err:      # noqa: BLE001 - the user's code, one line
            raise code_error(repr(self.name), self.folder, err) from err
        lo, hi = self.arity
        if not lo <= len(args) <= hi:
            takes = str(lo) if lo == hi else f"{lo}..{hi}"
            raise BehaviourError(
                f"behaviour {self.name!r}: robot_args in {self.folder / '__init__.py'} gives "
                f"{len(args)} arguments, but {self.robot_class.__name__}.__init__ in "
                f"{self.robot_module.__file__} takes {takes}; make them agree")
        return args

    @functools.cached_property
    def arity(self) -> tuple[int, float]:
        """(fewest, most) positional arguments the FSM's constructor takes
        (after self); most is infinite with *args."""
        import inspect
        cls: Any = self.robot_class        # a robot.py that fails to import: its one line
        try:
            sig = inspect.signature(cls.__init__)
        except (TypeError, ValueError):
            return 0, float("inf")
        params = list(sig.parameters.values())[1:]
        positional = [p for p in params if p.kind in (p.POSITIONAL_ONLY,
                                                       p.POSITIONAL_OR_KEYWORD)]
        lo = sum(1 for p in positional if p.default is p.empty)
        hi = float("inf") if any(p.kind == p.VAR_POSITIONAL for p in params) \
            else len(positional)
        return lo, hi

    def make_robot(self, node: int, seed: int, sc: Any) -> Any:
        return self.robot_class(*self.robot_args(node, seed, sc))

    def coordinator(self, sc: Any, **kw: Any) -> Any:
        try:
            return self.package.make_coordinator(sc, **kw)
        except SimError:
            raise
        except Exception as err:      # noqa: BLE001 - the user's code, one line
            raise code_error(repr(self.name), self.folder, err) from err

    def state_name(self, code: int) -> str:
        states = self.spec.STATES
        return states[code] if 0 <= code < len(states) else str(code)

    @property
    def reporters(self) -> tuple:
        """(name, meaning) of each per-tick reporter spec.REPORTERS declares
        (optional; none when absent)."""
        return tuple(getattr(self.spec, "REPORTERS", ()))

    def report(self, coordinator: Any) -> dict[str, Any]:
        """The declared reporters' values now, in declaration order."""
        if not self.reporters:
            return {}
        got = coordinator.reporters()
        missing = [name for name, _ in self.reporters if name not in got]
        if missing:
            raise BehaviourError(f"behaviour {self.name!r}: coordinator.reporters() lacks "
                                 f"{', '.join(missing)} (declared in spec.REPORTERS)")
        return {name: got[name] for name, _ in self.reporters}

    @property
    def halt_state(self) -> int:
        """The code of the state "halt" (every behaviour has one: the host's
        HALT ends a mission in it, and the bus tools wait for it)."""
        return self.spec.STATES.index("halt")

    @property
    def messages(self) -> tuple:
        """Its own messages (spec.MESSAGES; none when absent)."""
        return tuple(getattr(self.spec, "MESSAGES", ()))

    def activate(self) -> "Behaviour":
        """Make this the behaviour in use: its own message kinds join the
        link's (messages.activate), replacing those of any behaviour used
        before in this process; the CAN codec follows (bridge/links/codec.py).
        Loading never does this, so listing behaviours that give one kind
        different messages breaks none of them."""
        from firmware_logic import messages
        messages.activate(self.messages)
        global _ACTIVE
        _ACTIVE = self
        return self

    @property
    def studies(self) -> tuple:
        """Its studies (studies.py STUDIES: named sweeps and their figures as
        data, sim_backend/studies.py; none without that module). Host-side:
        no robot imports it, so deploy never copies it."""
        if not (self.folder / "studies.py").is_file():
            return ()
        try:
            mod = importlib.import_module(self.module_name + ".studies")
        except Exception as err:      # noqa: BLE001 - any error in the file, one line
            raise BehaviourError(f"behaviour {self.name!r}: {self.folder / 'studies.py'}: "
                                 f"{type(err).__name__}: {err}") from None
        if not hasattr(mod, "STUDIES"):
            raise BehaviourError(f"behaviour {self.name!r}: {self.folder / 'studies.py'} "
                                 "lacks STUDIES")
        return mod.STUDIES

    def modules(self) -> list[Path]:
        """The behaviour's firmware files (what deploy copies to a board)."""
        return sorted(p for p in self.folder.glob("*.py"))


_ACTIVE: Behaviour | None = None


def active() -> Behaviour:
    """The behaviour in use (the last activated; the thesis when none was)."""
    return _ACTIVE if _ACTIVE is not None else load().activate()


def builtin() -> dict[str, str]:
    """The packages in firmware_logic/behaviours/ (a new folder there is found
    without any registration)."""
    # plain os calls, not pathlib: every scenario and world loads its
    # behaviour (six times a sweep's run), and this listing was most of it
    where = str(BEHAVIOURS_DIR)
    with os.scandir(where) as it:
        found = sorted(e.name for e in it if e.is_dir())
    return {name: BUILTIN_PREFIX + name for name in found
            if os.path.isfile(os.path.join(where, name, "__init__.py"))
            and os.path.isfile(os.path.join(where, name, "spec.py"))}


@functools.lru_cache(maxsize=1)
def _entry_points() -> tuple[tuple[str, str], ...]:
    """The behaviours installed packages declare, read once per process:
    importlib.metadata reads every installed distribution's metadata on
    each call (13 ms in this venv), and every scenario and world loads its
    behaviour (a 512-run sweep chunk spent 13.6 of its 19.6 s here).
    Imported here: importlib.metadata (and the email, zipfile and csv
    modules under it) is most of a built-in behaviour's import cost, and a
    built-in is found without it (module_of)."""
    import importlib.metadata
    return tuple((ep.name, ep.value) for ep in importlib.metadata.entry_points(group=GROUP))


def names() -> dict[str, str]:
    """Every installed behaviour: name -> module (built-ins, then entry points)."""
    out = builtin()
    for name, value in _entry_points():
        out.setdefault(name, value)
    return out


def module_of(ref: str) -> str | None:
    """names().get(ref), reading the installed packages' entry points only
    for a name no built-in has (a built-in wins either way): `touchswarm
    run` of a built-in never imports importlib.metadata."""
    found = builtin().get(ref)
    if found is None:
        found = next((value for name, value in _entry_points() if name == ref), None)
    return found


def code_error(where: str, folder: Path, err: BaseException) -> BehaviourError:
    """An error raised by the behaviour's own code (a syntax error, an import
    or a call that fails) as one line naming its file and line: the deepest
    frame in the behaviour's folder, where the user can fix it."""
    import traceback
    if isinstance(err, SyntaxError):
        file, line, text = err.filename, err.lineno, f"SyntaxError: {err.msg}"
    else:
        frames = traceback.extract_tb(err.__traceback__)
        own = [f for f in frames if Path(f.filename).resolve().is_relative_to(folder)]
        where_from = own or frames
        file, line = ((where_from[-1].filename, where_from[-1].lineno) if where_from
                      else (None, None))
        text = f"{type(err).__name__}: {err}".splitlines()[0]
    at = f"{file} line {line}: " if file else ""
    if isinstance(err, ModuleNotFoundError) and str(err.name).split(".")[0] in (
            folder.name, where.strip("'")):
        # its own name exists on no board and in no other process
        text += ("; import the behaviour's own modules relatively (from .spec import ...; "
                 "docs/writing-a-behaviour.md, \"Imports\")")
    return BehaviourError(f"behaviour {where}: {at}{text}")


def failed_in(err: BaseException) -> BehaviourError | None:
    """An error raised by the code of a behaviour that is not built in (a
    folder, an installed package) while it ran (its step, its coordinator),
    as one line naming the behaviour and its file and line; None when no
    frame of such a behaviour's code raised it. A process pool's error
    carries the worker's frames as text (its cause), read here too."""
    import traceback
    own = {Path(b.package.__file__).resolve().parent: b for b in list(_LOADS.values())
           if not b.module_name.startswith(BUILTIN_PREFIX) and b.package.__file__}
    if not own:
        return None
    frames = [(f.filename, f.lineno, f.name) for f in traceback.extract_tb(err.__traceback__)]
    if err.__cause__ is not None and type(err.__cause__).__name__ == "_RemoteTraceback":
        frames += [(f, int(n), fn) for f, n, fn in
                   re.findall(r'File "([^"]+)", line (\d+), in (\S+)', str(err.__cause__))]
    for file, line, func in reversed(frames):
        path = Path(file).resolve()
        for folder, b in own.items():
            if path.is_relative_to(folder):
                text = f"{type(err).__name__}: {err}".splitlines()[0]
                return BehaviourError(f"behaviour {b.name!r} failed: {file} line {line} "
                                      f"in {func}: {text}")
    return None


def _check(mod: ModuleType, spec: ModuleType, where: str) -> None:
    missing = [k for k in SPEC_KEYS if not hasattr(spec, k)]
    if missing:
        raise BehaviourError(f"behaviour {where}: spec.py lacks {', '.join(missing)}")
    if "halt" not in spec.STATES:
        raise BehaviourError(f"behaviour {where}: spec.py STATES has no \"halt\" state "
                             "(the host's HALT must end a mission in it)")
    for attr in ("ROBOT", "robot_args", "make_coordinator"):
        if not hasattr(mod, attr):
            raise BehaviourError(f"behaviour {where}: __init__.py lacks {attr}")


def folder_module_name(path: Path) -> str:
    """The module name a behaviour folder is imported under: its folder's name
    plus a digest of its full path, so that it never shadows an installed
    behaviour (or another folder) of the same name in one process, and a
    worker process that loads the same folder gets the same name."""
    import hashlib      # only a folder behaviour needs it
    digest = hashlib.sha1(str(path).encode()).hexdigest()[:12]
    return "_touchswarm_folder_%s_%s" % (re.sub(r"\W", "_", path.name), digest)


def _import_folder(path: Path) -> ModuleType:
    init = path / "__init__.py"
    if not init.is_file():
        raise BehaviourError(f"behaviour folder {str(path)!r} has no __init__.py")
    name = folder_module_name(path)
    if name in sys.modules:
        return sys.modules[name]
    spec = importlib.util.spec_from_file_location(name, init,
                                                  submodule_search_locations=[str(path)])
    if spec is None or spec.loader is None:
        raise BehaviourError(f"behaviour folder {str(path)!r} cannot be imported")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod
    try:
        spec.loader.exec_module(mod)
    except BaseException:
        del sys.modules[name]       # a fixed file loads afresh on the next try
        raise
    return mod


# behaviour folders the user vouched for on the command line (`--behaviour
# DIR`, `--trust-behaviour DIR`): the only folders a data file may name
_TRUSTED: set[Path] = set()


def trust(ref: str | Path | None) -> None:
    """The user named `ref` on the command line: a folder it names may be
    named by data files too (named_by_data)."""
    if ref is not None and module_of(str(ref)) is None:
        _TRUSTED.add(Path(ref).resolve())


def untrust_all() -> None:
    """Forget every trusted folder (a new command in the same process)."""
    _TRUSTED.clear()


def named_by_data(ref: Any, source: str) -> None:
    """A data file (a scenario TOML, a recording's sidecar, a journal's
    meta) names behaviour `ref`: fine for an installed behaviour; a folder is
    code that would run on import, so only one the user trusted on the
    command line (`trust`). BehaviourError (one line) otherwise, before any
    import."""
    if ref is None or module_of(str(ref)) is not None:
        return
    if Path(str(ref)).resolve() in _TRUSTED:
        return
    raise BehaviourError(
        f"{source} names the behaviour folder {str(ref)!r}; a data file may name only an "
        f"installed behaviour ({', '.join(sorted(names()))}), since a folder's code runs "
        f"when it is loaded (docs/security.md, \"Trusted input\"); if you trust it, pass "
        f"--behaviour {ref} or --trust-behaviour {ref}")


def beside(ref: Any, here: Path) -> Any:
    """The behaviour a file in folder `here` names (a scenario, an
    experiment, a recording's sidecar): an installed one as it is; a folder
    relative to the file's folder, so the file and the behaviour travel
    together (relative to where the command runs, as older files meant it,
    only when just that one exists)."""
    if module_of(str(ref)) is not None:
        return ref
    own = Path(os.path.normpath(here / str(ref)))
    return str(own) if own.is_dir() or not Path(str(ref)).is_dir() else ref


# load()'s answers, by the reference, the working folder and the built-in
# folder's mtime (a folder added or removed there changes it): a sweep's run
# loads its behaviour some six times (scenario, world, engine, summary, row),
# and the folder listing and imports checked each time were most of it
_LOADS: dict[tuple[str, str, int], Behaviour] = {}


def load(ref: str | Path | None = None) -> Behaviour:
    """A behaviour by registered name (default "thesis") or folder path."""
    ref = "thesis" if ref is None else ref
    try:
        key = (str(ref), os.getcwd(), os.stat(BEHAVIOURS_DIR).st_mtime_ns)
    except OSError:
        key = None
    kept = _LOADS.get(key) if key is not None else None
    # the same modules still imported: a reloaded (edited) behaviour is loaded afresh
    if kept is not None and sys.modules.get(kept.module_name) is kept.package \
            and sys.modules.get(kept.spec.__name__) is kept.spec:
        return kept
    b = _load(ref)
    if key is not None:
        _LOADS[key] = b
    return b


def _load(ref: str | Path) -> Behaviour:
    modname = module_of(str(ref))
    if modname is not None:
        try:
            mod = importlib.import_module(modname)
        except ImportError as err:
            raise BehaviourError(f"behaviour {ref!r}: cannot import {modname}: {err}") from err
        where = repr(str(ref))
    else:
        path = Path(ref)
        if not path.is_dir():
            raise BehaviourError(f"behaviour {str(ref)!r}: not an installed behaviour "
                                 f"({', '.join(sorted(names()))}) nor a folder")
        where = repr(str(path))
        try:
            mod = _import_folder(path.resolve())
        except BehaviourError:
            raise
        except Exception as err:      # noqa: BLE001 - the user's __init__.py, one line
            raise code_error(where, path.resolve(), err) from err
    folder = Path(mod.__file__ or ".").resolve().parent
    if not (folder / "spec.py").is_file():
        raise BehaviourError(f"behaviour {where}: no spec.py in {folder}")
    try:
        spec = importlib.import_module(mod.__name__ + ".spec")
    except Exception as err:      # noqa: BLE001 - the user's spec.py, one line
        raise code_error(where, folder, err) from err
    _check(mod, spec, where)
    from firmware_logic import messages
    try:
        messages.check(getattr(spec, "MESSAGES", ()))
    except messages.SchemaError as err:
        raise BehaviourError(f"behaviour {where}: {spec.__file__}: MESSAGES: {err}") from err
    return Behaviour(spec.NAME, mod, spec)
