"""A behaviour's own scenario keys, read from its spec.PARAMS.

A PARAMS row is (name, default, low, high, meaning), in the firmware subset
(no floats on a board), so the kind of a key is read off its row:

    default an int                 an int in low..high (None: unbounded)
    default True or False          a bool (true/false)
    default, low, high as text     a float written as text ("1.0", "0.01", "655.0")
    default text, low a tuple      one of the tuple's words
    default text, low None         one of the behaviour's movement models
                                   (spec.MODELS names; their codes are accepted too)

Every parameter is a scenario key of scenarios that run the behaviour:
settable with --set, sweepable with --grid, written to summary.json and
sweep.csv, listed by `touchswarm scenarios --behaviour NAME`.
"""

from __future__ import annotations

import functools
from typing import Any, NamedTuple

from sim_backend.errors import ScenarioError


class Param(NamedTuple):
    """One parameter a behaviour declares (a spec.PARAMS row), its kind
    read off the row; check() takes a value to the one the scenario holds.
    A named tuple: made at import for every behaviour, where a frozen
    dataclass compiled its methods first (~2 M instructions)."""

    name: str
    kind: str                  # int, float, bool, choice
    default: Any
    low: Any = None
    high: Any = None
    choices: tuple = ()
    codes: tuple = ()          # ((code, name), ...) a choice also accepts: the models
    meaning: str = ""

    def allowed(self) -> str:
        """The allowed values, as the listings and errors show them."""
        if self.kind == "choice":
            return " | ".join(self.choices)
        if self.kind == "bool":
            return "true | false"
        lo = "" if self.low is None else self.low
        hi = "" if self.high is None else self.high
        return f"{lo}..{hi}"

    def check(self, value: Any) -> Any:
        """The value as this parameter holds it; ScenarioError naming the key
        and what is allowed when it is not one."""
        if self.kind == "choice":
            for code, name in self.codes:
                if not isinstance(value, bool) and value == code:
                    return name
            if isinstance(value, str):
                for name in self.choices:
                    if name.lower() == value.lower():
                        return name
            named = [f"{n!r} ({c})" for c, n in self.codes] or [repr(n) for n in self.choices]
            raise ScenarioError(f"{self.name}: expected one of {', '.join(named)}, "
                                f"got {value!r}")
        if self.kind == "bool":
            # sweep.csv cells read back (plots, figures, resume) say True/False
            value = {"True": True, "False": False, "true": True, "false": False}.get(
                value, value) if isinstance(value, str) else value
            if not isinstance(value, bool):
                raise ScenarioError(f"{self.name}: expected true or false, got {value!r}")
            return value
        ok_type = isinstance(value, (int, float)) and not isinstance(value, bool)
        if self.kind == "int" and ok_type and float(value).is_integer():
            value = int(value)
        if not ok_type or (self.kind == "int" and not isinstance(value, int)):
            raise ScenarioError(f"{self.name}: expected {self.kind} in {self.allowed()}, "
                                f"got {value!r}")
        if value != value or (self.low is not None and value < self.low) or \
                (self.high is not None and value > self.high):   # NaN compares False
            raise ScenarioError(f"{self.name}: {value!r} is outside the allowed range "
                                f"{self.allowed()}")
        return float(value) if self.kind == "float" else value


def _param(row: tuple, models: tuple, where: str) -> Param:
    if not isinstance(row, tuple) or len(row) != 5 or not isinstance(row[0], str):
        raise ScenarioError(f"behaviour {where}: spec.PARAMS row {row!r}: expected "
                            "(name, default, low, high, meaning)")
    name, default, lo, hi, meaning = row
    if isinstance(default, bool):
        return Param(name, "bool", default, meaning=meaning)
    if isinstance(default, int):
        return Param(name, "int", default, lo, hi, meaning=meaning)
    if isinstance(default, str) and isinstance(lo, tuple):
        if default not in lo:
            raise ScenarioError(f"behaviour {where}: spec.PARAMS {name}: default "
                                f"{default!r} is not one of {lo!r}")
        return Param(name, "choice", default, choices=tuple(lo), meaning=meaning)
    if isinstance(default, str) and lo is None and hi is None:
        names = tuple(n for _, n in models)
        if default not in names:
            raise ScenarioError(f"behaviour {where}: spec.PARAMS {name}: default "
                                f"{default!r} is not a model of spec.MODELS ({', '.join(names)})")
        return Param(name, "choice", default, choices=names, codes=tuple(models),
                     meaning=meaning)
    if isinstance(default, str):
        try:
            return Param(name, "float", float(default), None if lo is None else float(lo),
                         None if hi is None else float(hi), meaning=meaning)
        except (TypeError, ValueError):
            pass
    raise ScenarioError(f"behaviour {where}: spec.PARAMS row {row!r}: a default must be an "
                        "int, a bool, a float as text (\"1.0\"), or a word with its choices "
                        "as a tuple in the low slot")


@functools.lru_cache(maxsize=None)
def _declared(behaviour: str) -> tuple[Param, ...]:
    from sim_backend import registry
    try:
        b = registry.load(behaviour)
    except registry.BehaviourError as err:
        raise ScenarioError(f"behaviour: {err}") from err
    rows = tuple(getattr(b.spec, "PARAMS", ()))
    out = tuple(_param(r, tuple(b.spec.MODELS), repr(behaviour)) for r in rows)
    seen = set()
    for p in out:
        if p.name in seen:
            raise ScenarioError(f"behaviour {behaviour!r}: spec.PARAMS declares "
                                f"{p.name!r} twice")
        seen.add(p.name)
    return out


def declared(behaviour: str, world_keys: frozenset[str] = frozenset()) -> tuple[Param, ...]:
    """The behaviour's parameters; a name that is a world key is refused
    (it would shadow the world's own)."""
    out = _declared(str(behaviour))
    for p in out:
        if p.name in world_keys:
            raise ScenarioError(f"behaviour {behaviour!r}: spec.PARAMS {p.name!r} is a "
                                "world key of the scenario; rename the parameter")
    return out


def defaults(behaviour: str) -> tuple[tuple[str, Any], ...]:
    """((name, default), ...) in declaration order."""
    return tuple((p.name, p.default) for p in _declared(str(behaviour)))


def names(behaviour: str) -> tuple[str, ...]:
    return tuple(p.name for p in _declared(str(behaviour)))
