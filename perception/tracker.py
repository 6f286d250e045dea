"""Perception as a run's measure: the evidence, estimate and recognition
updated every tick of a simulated run (issue 13, step 3: a measure, not yet
a decision; nothing here commands a robot).

`Perceiver(engine)` watches an Engine through its observer seam
(sim_backend/observe.py): after every tick it adds the host's new touches
(object cells, in the object's frame) and the cells the robots stand on
(free; every `free_every` ticks: 1 is the simulation's full view, 64 what
today's search-phase HEARTBEATs carry), recomputes the recognition when the
evidence near the touches changed, and keeps the new estimate's IoU with
the truth per tick. It adds trace columns (COLUMNS) and summary fields
(`summary()`) through `engine.instruments`.
"""

from __future__ import annotations

import logging
from typing import Any, NamedTuple

from firmware_logic import fixedpoint as fx
from perception.evidence import Evidence, iou
from perception.recognise import THRESHOLD, Recognition, estimate, recognise
from perception.shapes import Library

log = logging.getLogger(__name__)

COLUMNS = (("estimate_iou", "IoU of the new shape estimate (recognised shape's MAP placement, "
                            "else the hull minus known-free cells) with the true shape"),
           ("recognised_p", "posterior of the most probable library shape (0 before a touch)"))


class AtTouches(NamedTuple):
    """The host's view when its k-th touch arrived."""
    tick: int
    estimate_iou: float       # the new estimate
    hull_free_iou: float      # the hull minus known-free cells (no library)
    hull_iou: float           # the touched cells' hull (summary shape_iou's outline)
    best: str | None          # the most probable library shape
    p: float                  # its posterior


class Perceiver:
    def __init__(self, engine: Any, library: Library | None = None,
                 threshold: float = THRESHOLD, free_every: int = 1, every: int = 16,
                 watch: bool = True) -> None:
        """free_every: take the robots' cells as free every that many ticks
        (0: never). every: recompute the recognition at each new touch, and
        when free cells near the touches changed, at most once per `every`
        ticks (it costs tens of ms). watch: update after every tick through
        the engine's observer seam; False: the caller calls update()."""
        if not 0.0 < threshold <= 1.0:
            raise ValueError(f"threshold {threshold}: expected in (0, 1]")
        if free_every < 0:
            raise ValueError(f"free_every {free_every}: expected >= 0 (0: no free evidence)")
        if every < 1:
            raise ValueError(f"every {every}: expected >= 1 tick")
        self.every = every
        self.computed = -1                # the tick of the last recognition
        self.pending = False              # free evidence near the touches not yet used
        self.engine = engine
        self.library = library if library is not None else Library.of(engine.sc)
        self.threshold = threshold
        self.free_every = free_every
        self.ev = Evidence(engine.sc.worldSize)
        w = engine.world
        # the truth in the object's frame: where it stands at the start
        # (the target's cells as the world placed them: a built-in or a drawn object)
        self.truth = set(w.object_cells)
        self.start = w.object_cells[0]
        self.extent = self.library.extent()
        self.rec = recognise(self.ev, self.library)
        self.est: set[tuple[int, int]] = set()
        self.seen = 0                     # touches already in the evidence
        self.tick = -1                    # the tick the evidence is up to
        self.recognised_tick: int | None = None
        self.recognised_as: str | None = None
        self.curve: list[tuple[int, float, float]] = []   # (tick, estimate IoU, p)
        # per number of touches k: what the host knew when the k-th arrived
        self.by_touches: dict[int, AtTouches] = {}
        if watch:
            engine.observe(lambda snap: self.update())
        instruments = getattr(engine, "instruments", None)
        if instruments is not None:
            instruments.append(self)
        self.update()

    # -- per tick --------------------------------------------------------------

    def update(self) -> None:
        """Bring the evidence up to the engine's tick (idempotent within a tick)."""
        e = self.engine
        if self.tick == e.tick:
            return
        self.tick = e.tick
        c = e.coordinator
        touches = getattr(c, "touches", ())
        touched = False
        for t in touches[self.seen:]:
            touched |= self.ev.touch(t.sx, t.sy)
        self.seen = len(touches)
        if self.free_every and e.tick % self.free_every == 0:
            w = e.world
            cx, cy = w.object_cells[0]
            mx, my = cx - self.start[0], cy - self.start[1]   # how far the object moved
            near = self._window()
            for x, y in zip(w.xs, w.ys):
                px, py = fx.patch(x) - mx, fx.patch(y) - my
                if self.ev.free(px, py) and near is not None:
                    self.pending |= near[0] <= px <= near[1] and near[2] <= py <= near[3]
        # the last tick of a run uses every piece of evidence, so the trace's
        # last row and the summary agree
        due = e.tick - self.computed >= self.every or e.finished()
        if touched or (self.pending and due):
            self._recompute()
        self._record()

    def _recompute(self) -> None:
        e = self.engine
        self.pending = False
        self.computed = e.tick
        self.rec = recognise(self.ev, self.library)
        self.est = estimate(self.ev, self.rec, self.threshold)
        if self.recognised_tick is None and self.rec.recognised(self.threshold):
            self.recognised_tick = e.tick
            self.recognised_as = self.rec.best
            log.info("recognised %s (p %.3f) at tick %d", self.rec.best, self.rec.p, e.tick)

    def _record(self) -> None:
        e = self.engine
        est_iou = iou(self.est, self.truth)
        self.curve.append((e.tick, est_iou, self.rec.p if self.ev.touched else 0.0))
        k = len(self.ev.touched)
        if k and k not in self.by_touches:
            entry = AtTouches(e.tick, est_iou, iou(self.ev.hull_estimate(), self.truth),
                              iou(self.ev.hull_cells(), self.truth), self.rec.best, self.rec.p)
            for j in range(len(self.by_touches) + 1, k + 1):   # touches arriving together
                self.by_touches[j] = entry

    def _window(self) -> tuple[int, int, int, int] | None:
        """Where a free cell can change the recognition: the touches' box
        widened by the largest shape (None before a touch)."""
        if not self.ev.touched:
            return None
        xs = [c[0] for c in self.ev.touched]
        ys = [c[1] for c in self.ev.touched]
        d = self.extent
        return min(xs) - d, max(xs) + d, min(ys) - d, max(ys) + d

    # -- what a run reports -----------------------------------------------------

    COLUMNS = COLUMNS

    def row(self) -> list[Any]:
        self.update()
        _, est_iou, p = self.curve[-1]
        return [est_iou, round(p, 6)]

    def recognition(self) -> Recognition:
        return self.rec

    def summary(self) -> dict[str, Any]:
        self.update()
        rec = self.rec
        return {
            "estimate_iou": iou(self.est, self.truth),
            "estimate_kind": ("none" if not self.ev.touched else
                              "map" if rec.recognised(self.threshold) else "hull-free"),
            "hull_free_iou": iou(self.ev.hull_estimate(), self.truth),
            "recognised": rec.best if rec.recognised(self.threshold) else None,
            "recognised_p": round(rec.p, 6) if self.ev.touched else 0.0,
            "recognised_tick": self.recognised_tick,
            "recognised_as": self.recognised_as,
            "recognition_threshold": self.threshold,
            "evidence": {**self.ev.uncertainty(), "free_seen": self.ev.free_cells,
                         "conflicts": self.ev.conflicts},
        }


def attach(engine: Any, **kw: Any) -> Perceiver | None:
    """A Perceiver on the engine when its behaviour perceives an object: its
    coordinator keeps touched segments (`touches`, each with sx, sy) of an
    object it tracks as it moves (`moved_x`), as the thesis's does; None
    otherwise (aggregate, whose stops are robots, not an object)."""
    c = engine.coordinator
    if not hasattr(c, "touches") or not hasattr(c, "moved_x"):
        return None
    return Perceiver(engine, **kw)
