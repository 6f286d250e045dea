"""What the live view's side panels are made of, derived from the scenario
and the behaviour's declarations, never named here:

plots       one small line plot per panel: robots per state (spec.STATES),
            touches, the load pair (spec.LOAD, e.g. held vs needed), the
            shape's score (spec.SHAPE) and every declared reporter
            (spec.REPORTERS), each titled by its meaning (sim_backend/words.py)
History     the plotted values tick by tick, thinned to at most MAX_POINTS
            per poll (the newest always kept)
fields      the parameters panel: the world's keys with their ranges
            (sim_backend/scenario.py RANGES, CHOICES) and the behaviour's
            own (spec.PARAMS through sim_backend/params.py), current values
"""

from __future__ import annotations

import math
from typing import Any

MAX_POINTS = 400          # points per series a poll carries
LINE = "#222222"
HELD, NEEDED = "#2a6fdb", "#cc0000"


def state_key(name: str) -> str:
    return "state:" + name


def plots(behaviour: Any, colours: list[str], shape: bool = True,
          instruments: tuple = ()) -> list[dict[str, Any]]:
    """The plot panels of a behaviour, in the order the page shows them.
    `shape`: whether the source can score the shape (a simulation knows the
    true object; a host does not). `instruments`: the engine's (each with
    COLUMNS, ((name, meaning), ...), and row(); e.g. perception's shape
    estimate and recognition), one plot per column."""
    from sim_backend import words
    w = words.of(behaviour)
    names = tuple(behaviour.spec.STATES)
    out: list[dict[str, Any]]
    out = [{"id": "states", "title": "robots per state", "unit": "robots",
            "series": [{"key": state_key(n), "label": n, "colour": c}
                       for n, c in zip(names, colours)]},
           {"id": "touches", "title": "touches the host accepted", "unit": "touches",
            "series": [{"key": "touches", "label": "touches", "colour": LINE}]}]
    if w.load is not None:
        held, need = w.load
        out.append({"id": "load", "title": f"{held} held vs {need}", "unit": "weight units",
                    "series": [{"key": held, "label": held, "colour": HELD},
                               {"key": need, "label": need, "colour": NEEDED}]})
    if w.shape is not None and shape:
        out.append({"id": "shape", "title": w.title(w.shape), "unit": "0..1", "range": [0, 1],
                    "series": [{"key": w.shape, "label": w.label(w.shape), "colour": LINE}]})
    for name, title in w.reporters:
        out.append({"id": "r-" + name, "title": title, "unit": name,
                    "series": [{"key": name, "label": name, "colour": LINE}]})
    for inst in instruments:
        for name, title in inst.COLUMNS:
            out.append({"id": "i-" + name, "title": title, "unit": name,
                        "series": [{"key": name, "label": name, "colour": LINE}]})
    return out


def instrument_values(instruments: tuple) -> dict[str, Any]:
    """The instruments' columns now (their trace row), numbers only."""
    return {name: _number(v) for inst in instruments
            for (name, _), v in zip(inst.COLUMNS, inst.row())}


def _number(v: Any) -> float | int | None:
    if isinstance(v, bool):
        return int(v)
    return v if isinstance(v, (int, float)) and v == v else None


def sample(behaviour: Any, coord: Any, states: tuple[int, ...] | None = None,
           shape_score: float | None = None) -> dict[str, Any]:
    """One tick's plotted values from the host coordinator (and, when known,
    the robots' state codes and the shape's score)."""
    from sim_backend import words
    w = words.of(behaviour)
    out: dict[str, Any] = {"touches": len(coord.touches)}
    if states is not None:
        names = tuple(behaviour.spec.STATES)
        counts = [0] * len(names)
        for s in states:
            counts[s] += 1
        out.update({state_key(n): k for n, k in zip(names, counts)})
    if w.load is not None:
        for name in w.load:
            out[name] = getattr(coord, name) / 100
    if w.shape is not None and shape_score is not None:
        out[w.shape] = shape_score
    for name, v in behaviour.report(coord).items():
        out[name] = _number(v)
    return out


class History:
    """Plotted values by tick; a tick sampled twice keeps its newest values."""

    def __init__(self) -> None:
        self.ticks: list[int] = []
        self.rows: list[dict[str, Any]] = []

    def add(self, tick: int, values: dict[str, Any]) -> None:
        if self.ticks and self.ticks[-1] == tick:
            self.rows[-1] = {**self.rows[-1], **values}
        else:
            self.ticks.append(tick)
            self.rows.append(values)

    def __len__(self) -> int:
        return len(self.ticks)

    def columns(self, keys: list[str], max_points: int = MAX_POINTS) -> dict[str, list]:
        """{"tick": [...], key: [...]} at most max_points long, the newest
        tick always last; a value not sampled at a tick carries the one
        before it (None before the first)."""
        stride = max(1, math.ceil(len(self.ticks) / max_points))
        pick = list(range(0, len(self.ticks), stride))
        if pick and pick[-1] != len(self.ticks) - 1:
            pick.append(len(self.ticks) - 1)
        out: dict[str, list] = {"tick": [self.ticks[i] for i in pick]}
        last: dict[str, Any] = {}
        chosen = set(pick)
        cols: dict[str, list] = {k: [] for k in keys}
        for i, row in enumerate(self.rows):
            last.update(row)
            if i in chosen:
                for k in keys:
                    cols[k].append(last.get(k))
        out.update(cols)
        return out


def series_keys(panels: list[dict[str, Any]]) -> list[str]:
    return [s["key"] for p in panels for s in p["series"]]


# -- the parameters panel ----------------------------------------------------


def fields(sc: Any) -> list[dict[str, Any]]:
    """Every key the panel offers: name, group, kind (int, float, bool,
    choice), range or choices, meaning, the scenario's value now. The link's
    own fault keys are left out (they need a real link: `run --link can`)."""
    from sim_backend import objects, params
    from sim_backend import scenario as S
    now = sc.to_dict()
    out: list[dict[str, Any]] = []
    for key, (kind, lo, hi) in S.RANGES.items():
        if key in S.LINK_FAULT_KEYS:
            continue
        out.append({"name": key, "group": "world", "kind": kind.__name__, "low": lo,
                    "high": hi, "value": now[key],
                    "meaning": "empty: drawn at random" if key in ("objectX", "objectY") else ""})
    out.append({"name": "object", "group": "world", "kind": "choice",
                "choices": sorted(objects.SHAPES) + [objects.NONE], "value": now["object"],
                "meaning": ""})
    for key, choices in S.CHOICES.items():
        out.append({"name": key, "group": "world", "kind": "choice", "choices": list(choices),
                    "value": now[key], "meaning": ""})
    for p in params.declared(sc.behaviour):
        out.append({"name": p.name, "group": f"behaviour {sc.behaviour}", "kind": p.kind,
                    "low": p.low, "high": p.high, "choices": list(p.choices),
                    "value": now[p.name], "meaning": p.meaning})
    return out
