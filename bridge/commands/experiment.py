"""Experiment files for `touchswarm sweep exp.toml` (BehaviorSpace experiments).

An experiment is a TOML file with the sweep's settings, the same as the
command line's options of the same names (docs/outputs.md, "Experiment
files"):

    scenario = "default"                 # built-in name or a .toml file
    seeds = 20                           # a count N, "A-B", or a list [1, 5, 9]
    engine = "auto"
    until = "delivered"
    out = "sweep-out"
    [grid]
    agents = [10, 20, 40]                # world keys or the behaviour's own
    sigRadius = [3, 5]                   # (`touchswarm scenarios --behaviour NAME`)
    [set]
    maxTicks = 3000

Relative paths in the file (scenario, out, a behaviour folder in [set] or
[grid]) are relative to the file's folder, so an experiment and its
scenario and behaviour travel together; a folder it names is loaded only
when the command line trusts it (--trust-behaviour DIR, docs/security.md). Every key is
checked on load; an unknown key or a wrong type is a one-line UsageError.
"""

from __future__ import annotations

import os
import tomllib
from pathlib import Path
from typing import Any

from bridge.errors import UsageError
from sim_backend.sweep import ENGINES

# key -> (TOML types allowed, what it holds)
KEYS: dict[str, tuple[tuple[type, ...], str]] = {
    "scenario": ((str,), "a built-in scenario name or a .toml file"),
    "grid": ((dict,), "a table KEY = [V1, V2, ...]"),
    "set": ((dict,), "a table KEY = VALUE applied to every point"),
    "seeds": ((int, str, list), 'a count N, a range "A-B" or a list of seeds'),
    "engine": ((str,), " or ".join(", ".join(ENGINES).rsplit(", ", 1))),
    "until": ((str,), "delivered or converged"),
    "out": ((str,), "the output directory"),
    "executor": ((str,), "processes[:N], inline or dask://HOST:PORT"),
    "chunk": ((int,), "runs per task, at least 1"),
}


def load(path: Path) -> dict[str, Any]:
    """The settings of an experiment file, checked and with paths resolved."""
    from sim_backend.textfile import TextFileError, read_small_text
    try:
        raw = tomllib.loads(read_small_text(path))
    except TextFileError as err:
        raise UsageError(f"experiment {path}: {err}; expected a TOML file") from None
    except tomllib.TOMLDecodeError as err:
        raise UsageError(f"experiment {path}: not valid TOML: {err}") from None
    for key, value in raw.items():
        if key not in KEYS:
            raise UsageError(f"experiment {path}: unknown key {key!r}; known keys: "
                             f"{', '.join(KEYS)}")
        types, what = KEYS[key]
        if not isinstance(value, types) or isinstance(value, bool):
            raise UsageError(f"experiment {path}: {key} = {value!r}; expected {what}")
    if "grid" not in raw:
        raise UsageError(f"experiment {path}: no [grid] table; expected e.g. "
                         "[grid] agents = [10, 20, 40]")
    for key, values in raw["grid"].items():
        if not isinstance(values, list) or not values:
            raise UsageError(f"experiment {path}: grid.{key} = {values!r}; expected a "
                             "non-empty list of values")
    if isinstance(raw.get("seeds"), list) and not all(
            isinstance(s, int) and not isinstance(s, bool) for s in raw["seeds"]):
        raise UsageError(f"experiment {path}: seeds = {raw['seeds']!r}; expected a list "
                         "of integer seeds")
    here = path.parent
    if "scenario" in raw:
        from sim_backend.scenario import builtin_names
        if raw["scenario"] not in builtin_names() and not Path(raw["scenario"]).is_absolute():
            raw["scenario"] = str(here / raw["scenario"])
    if "out" in raw:
        raw["out"] = here / raw["out"]
    if "behaviour" in raw.get("set", {}):
        raw["set"]["behaviour"] = _named_folder(raw["set"]["behaviour"], here, path)
    if "behaviour" in raw["grid"]:
        raw["grid"]["behaviour"] = [_named_folder(v, here, path) for v in raw["grid"]["behaviour"]]
    return raw


def _named_folder(ref: Any, here: Path, path: Path) -> Any:
    """A behaviour the file names, relative to its folder (registry.beside),
    and named by data: loaded only when the command line trusted it
    (docs/security.md, "Trusted input")."""
    from sim_backend import registry
    ref = registry.beside(ref, here)
    try:
        registry.named_by_data(ref, f"experiment {path}")
    except registry.BehaviourError as err:
        raise UsageError(str(err)) from None
    return ref


def seeds_text(seeds: int | str | list) -> str:
    """An experiment's seeds as the --seeds option spells them."""
    if isinstance(seeds, list):
        return ",".join(str(s) for s in seeds)
    return str(seeds)


def _toml(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, list):
        return "[" + ", ".join(_toml(v) for v in value) + "]"
    text = str(value).replace("\\", "\\\\").replace('"', '\\"')
    return f'"{text}"'


def _behaviour_text(value: Any, here: Path) -> Any:
    """A behaviour as the file names it: an installed one by name, a folder
    relative to the file's folder (load reads it back from there)."""
    from sim_backend import registry
    if isinstance(value, list):
        return [_behaviour_text(v, here) for v in value]
    if registry.module_of(str(value)) is not None:
        return value
    return os.path.relpath(Path(str(value)).resolve(), here)


def save(path: Path, settings: dict[str, Any]) -> Path:
    """Write settings (the keys of KEYS) as an experiment file that load()
    reads back to the same sweep; paths are written relative to its folder."""
    here = path.resolve().parent
    lines = ["# touchswarm experiment: run with `touchswarm sweep " + path.name + "`"]
    tables = []
    for key in KEYS:
        value = settings.get(key)
        if value is None:
            continue
        if key in ("grid", "set"):
            if value:
                tables.append((key, value))
            continue
        if key == "out" or (key == "scenario" and (Path(str(value)).suffix == ".toml"
                                                   or os.sep in str(value))):
            value = os.path.relpath(Path(value).resolve(), here)
        lines.append(f"{key} = {_toml(value)}")
    for key, table in tables:
        lines.append(f"\n[{key}]")
        lines += [f"{k} = {_toml(_behaviour_text(v, here) if k == 'behaviour' else v)}"
                  for k, v in table.items()]
    path.write_text("\n".join(lines) + "\n")
    return path
