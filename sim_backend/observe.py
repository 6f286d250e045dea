"""Per-tick snapshots of a run, built in one place for every observer.

`Engine.observe(fn)` calls fn(snapshot) after each tick (tick semantics:
after the moves and the host exchange). The trace (sim_backend/trace.py),
the animation (sim_backend/animate.py) and the trails on world.png
(`Trails` here) all read these. An engine with no observer builds none, so
a plain run pays nothing.

The cheap parts are copied into the snapshot; the rest (positions, states,
the perceived outline, the IoUs, ...) are built on their first read, so an
observer that reads none of them (the Perceiver's) costs a run nothing, and a
snapshot an observer keeps is completed before the next tick (freeze). The
two grids (field, object colours) are copied only when an observer asks, and
only during its call.
"""

from __future__ import annotations

from typing import Any, Callable

import numpy as np

from firmware_logic import fixedpoint as fx
from firmware_logic import perception
from sim_backend.errors import SimError
from sim_backend.measures import polygon_iou, power_held, shape_iou


class OutputFormatError(SimError, ValueError):
    """An output path (trace, animation) whose suffix names no format we write."""


def output_format(path: Any, suffixes: tuple[str, ...], what: str) -> str:
    """The format a path's suffix picks among `suffixes` ("csv" for ".csv")."""
    from pathlib import Path
    suffix = Path(path).suffix.lower()
    if suffix not in suffixes:
        raise OutputFormatError(f"{path}: unknown {what} format {suffix or '(no suffix)'!r}; "
                                f"expected one of {', '.join(suffixes)}")
    return suffix[1:]


class Snapshot:
    """The world and the host's view after one tick (tick 0: the start).

    xs, ys        robot positions in patches (floats), node order
    states        robot state codes; state_names maps a code to its name
    touches       accepted touches in arrival order: (node, tick, rx, ry)
    holders       nodes whose touch the host accepted, first touch first
    power         holders' power in weight units (summary "power")
    perceived     cells of the perceived shape; iou its IoU with the object
    polygon_iou   IoU with the object of the cells the holders' polygon encloses
    object_cells  the object's cells where they are now
    msgs_up/down  messages the host received / sent this tick
    bad_frames    frames the link refused this tick (0 on an in-process link)
    reporters     the behaviour's declared per-tick reporters (spec.REPORTERS)
    """

    __slots__ = ("tick", "xs", "ys", "states", "state_names", "touches", "holders", "power",
                 "perceived", "iou", "polygon_iou", "object_cells", "msgs_up", "msgs_down", "bad_frames",
                 "reporters", "home", "_world", "_engine")

    def __init__(self, **kw: Any) -> None:
        for k, v in kw.items():
            setattr(self, k, v)

    def __getattr__(self, name: str) -> Any:
        # only a field not set yet gets here: one of LAZY, built from the
        # engine as it stands (still this tick: see freeze), then kept
        build = _LAZY.get(name)
        engine = getattr(self, "_engine", None) if build is not None else None
        if build is None or engine is None:
            raise AttributeError(f"{type(self).__name__!r} object has no attribute {name!r}")
        v = build(engine)
        setattr(self, name, v)
        return v

    def freeze(self) -> None:
        """Build every field not built yet and let go of the engine: a
        snapshot kept past its tick holds that tick's values."""
        for name in _LAZY:
            getattr(self, name)
        self._engine = None

    def field(self) -> np.ndarray:
        """The potential field now, (n, n), row = y; a copy."""
        w = self._world
        return np.array(w.field, dtype=np.int32).reshape(w.n, w.n)

    def obj(self) -> np.ndarray:
        """The patches' object colours now (kernel FREE/YELLOW/BLUE), (n, n); a copy."""
        w = self._world
        return np.array(w.obj, dtype=np.int8).reshape(w.n, w.n)

    def counts(self) -> dict[str, int]:
        """Robots per state, by state name, every declared state present."""
        out = dict.fromkeys(self.state_names, 0)
        for s in self.states:
            out[self.state_names[s]] += 1
        return out


def bad_frames_total(link: Any) -> int:
    """Every frame the link (sim_backend/link.py) has refused so far."""
    return sum(link.bad_frames().values())


def snapshot(engine: Any) -> Snapshot:
    """The one builder of a Snapshot; it also advances the engine's bad-frame
    mark, so call it once per tick (Engine.step does). The fields in _LAZY
    are built on their first read (most of a snapshot's cost: the perceived
    outline and the IoUs), so an observer that reads none of them (the
    Perceiver's) costs nothing; call freeze() before the engine steps again
    if the snapshot is kept (Engine.step does when an observer kept it)."""
    w = engine.world
    bad = bad_frames_total(engine.link)
    fresh, engine.bad_seen = bad - engine.bad_seen, bad
    return Snapshot(
        tick=engine.tick, state_names=tuple(engine.behaviour.spec.STATES),
        msgs_up=engine.msgs_up, msgs_down=engine.msgs_down, bad_frames=fresh,
        home=(w.sc.homeX, w.sc.homeY), _world=w, _engine=engine)


def _xs(engine: Any) -> tuple[float, ...]:
    one = float(fx.ONE)
    return tuple(x / one for x in engine.world.xs)


def _ys(engine: Any) -> tuple[float, ...]:
    one = float(fx.ONE)
    return tuple(y / one for y in engine.world.ys)


# a Snapshot's fields built on their first read, each from the engine
_LAZY: dict[str, Callable[[Any], Any]] = {
    "xs": _xs,
    "ys": _ys,
    "states": lambda e: tuple(r.state for r in e.robots),
    "touches": lambda e: tuple((t.node, t.tick, t.rx, t.ry) for t in e.coordinator.touches),
    "holders": lambda e: tuple(dict.fromkeys(t.node for t in e.coordinator.touches)),
    "power": lambda e: power_held(e.coordinator),
    "perceived": lambda e: perception.outline_cells(e.coordinator.segments_now()),
    "iou": lambda e: shape_iou(e.coordinator, e.world),
    "polygon_iou": lambda e: polygon_iou(e.coordinator, e.world),
    "object_cells": lambda e: list(e.world.object_cells),
    "reporters": lambda e: e.behaviour.report(e.coordinator),
}


class Trails:
    """Every robot's position and state at every tick from the start, and the
    object's centre: what world.png and the animation draw trails from."""

    def __init__(self, engine: Any) -> None:
        self.xs: list[tuple[float, ...]] = []
        self.ys: list[tuple[float, ...]] = []
        self.states: list[tuple[int, ...]] = []
        self.centre: list[tuple[float, float]] = []
        self.add(engine.snapshot())
        engine.observe(self.add)

    def add(self, s: Snapshot) -> None:
        self.xs.append(s.xs)
        self.ys.append(s.ys)
        self.states.append(s.states)
        if s.object_cells:          # a world with no object has no centre to follow
            cx = sum(c[0] for c in s.object_cells) / len(s.object_cells)
            cy = sum(c[1] for c in s.object_cells) / len(s.object_cells)
            self.centre.append((cx, cy))

    def arrays(self, upto: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """xs, ys, states as (ticks, robots) arrays up to index `upto` (inclusive)."""
        end = len(self.xs) if upto is None else upto + 1
        return (np.array(self.xs[:end]), np.array(self.ys[:end]), np.array(self.states[:end]))
