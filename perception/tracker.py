"""Perception as a run's measure: the evidence, estimate and recognition
updated every tick of a simulated run (a measure, not a decision: nothing
here commands a robot).

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

from typing import Any, NamedTuple, Sequence

from firmware_logic import fixedpoint as fx
from perception import INFO, detail
from perception.evidence import Evidence, iou
from perception.recognise import THRESHOLD, Recognition, estimate, recognise, recognise_all
from perception.shapes import Library


COLUMNS = (("estimate_iou", "IoU of the new shape estimate (recognised shape's MAP placement, "
                            "else the hull minus known-free cells) with the true shape"),
           ("recognised", "the verdict: the recognised shape (or unknown) once its posterior "
                          "reaches the threshold, else empty"),
           ("p", "the verdict's posterior: the most probable hypothesis's (0 before a touch); "
                 "with recognise = true the decision's P(target)"))


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
        # with recognise = true the host's decider judges the touches: its
        # verdict is the run's, one posterior for the decision and for what
        # the run reports
        from sim_backend.coordinator import Recognising
        c = engine.coordinator
        self.decider = c.decider if isinstance(c, Recognising) else None
        if library is None:
            library = self.decider.library if self.decider is not None else Library.of(engine.sc)
        self.library = library
        if self.decider is not None:
            threshold = c.confidence / 1000
        self.threshold = threshold
        self.free_every = free_every
        self.ev = Evidence(engine.sc.worldSize)
        w = engine.world
        # the truth in the object's frame: where it stands at the start
        # (the target's cells as the world placed them: a built-in or a drawn object)
        self.truth = set(w.start_cells)
        self.start = w.start_cells[0]
        self.extent = self.library.extent()
        self.rec = recognise(self.ev, self.library)
        self.est: set[tuple[int, int]] = set()
        self.seen = 0                     # touches already in the evidence
        self.tick = -1                    # the tick the evidence is up to
        self.recognised_tick: int | None = None
        self.recognised_as: str | None = None
        self.curve: list[tuple[int, float, str | None, float]] = []  # tick, IoU, verdict, p
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
        for t in touches:          # a released touch leaves the list: no index into it
            touched |= self.ev.touch(t.sx, t.sy)
        self.seen = len(self.ev.touched)
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
            detail(__name__, INFO, "recognised %s (p %.3f) at tick %d", self.rec.best,
                   self.rec.p, e.tick)

    def verdict(self) -> tuple[set, str | None, float, str]:
        """The run's verdict now: (estimate cells, recognised or None, p,
        kind). With a decider, its call on the cluster the decision took
        (before the decision: its surest call so far); else this
        perceiver's own posterior."""
        if self.decider is not None:
            return decision_verdict(self.engine.coordinator)
        if not self.ev.touched:
            return self.est, None, 0.0, "none"
        rec = self.rec
        sure = rec.recognised(self.threshold)
        kind = "map" if sure and not rec.unknown else "hull-free"
        return self.est, rec.best if sure else None, round(rec.p, 6), kind

    def _record(self) -> None:
        e = self.engine
        est, name, p, _ = self.verdict()
        est_iou = iou(est, self.truth)
        self.curve.append((e.tick, est_iou, name, p))
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
        _, est_iou, name, p = self.curve[-1]
        return [est_iou, name or "", p]

    def recognition(self) -> Recognition:
        return self.rec

    def summary(self) -> dict[str, Any]:
        self.update()
        est, name, p, kind = self.verdict()
        c = self.engine.coordinator
        if self.decider is not None:
            when = c.target_tick if c.target_tick >= 0 else None
            first = self.decider.target_name if when is not None else None
        else:
            when, first = self.recognised_tick, self.recognised_as
        return {
            "estimate_iou": iou(est, self.truth),
            "estimate_kind": kind,
            "hull_free_iou": iou(self.ev.hull_estimate(), self.truth),
            "recognised": name,
            "p": p,
            "recognised_tick": when,
            "recognised_as": first,
            "recognition_threshold": self.threshold,
            "verdict_by": "decision" if self.decider is not None else "perception",
            "evidence": {**self.ev.uncertainty(), "free_seen": self.ev.free_cells,
                         "conflicts": self.ev.conflicts},
        }

    def estimate_view(self) -> tuple[set, str | None, float]:
        """The estimate now, in the object's own frame, with its verdict and
        posterior: what world.png and the animation draw (sim_backend/render.py)."""
        est, name, p, _ = self.verdict()
        return set(est), name, p


Verdict = tuple  # (estimate cells, recognised or None, p, estimate kind)


def decision_verdict(c: Any) -> Verdict:
    """A recognising coordinator's verdict: its decider's call on the
    cluster the decision took (before the decision, its surest call so
    far). The decision and the run's perception fields are this one call."""
    d = c.decider
    call = d.verdict(c.target_cells) if c.target_tick >= 0 else None
    if call is None:
        call = d.best
    if call is None:
        return set(), None, 0.0, "none"
    sure = c.target_tick >= 0 and call.permille >= c.confidence
    kind = "map" if call.rec.recognised(THRESHOLD) and not call.rec.unknown else "hull-free"
    return call.estimate, d.target_name if sure else None, round(call.permille / 1000, 6), kind


def perceives(c: Any) -> bool:
    """Whether a coordinator keeps touched segments of an object it tracks
    as it moves (`touches` with sx, sy; `moved_x`), as the thesis's does."""
    from sim_backend.coordinator import Tracking, has
    return has(c, Tracking)


END_FIELDS = ("estimate_iou", "recognised", "p")


def end_fields(result: Any) -> dict[str, Any]:
    """estimate_iou, recognised and p of a finished run that no Perceiver
    watched (a sweep's runs, either engine): the decision's verdict with
    recognise = true; else a posterior from the end state alone, the
    touches and the cells the robots stand on at the end (the per-tick free
    evidence of a watched run is not kept). {} for a behaviour that
    perceives no object."""
    return end_fields_all([result])[0]


def end_fields_all(results: Sequence[Any]) -> list[dict[str, Any]]:
    """end_fields of every result, the posteriors of those that share a
    library in one recognise_all (a sweep's chunk: the same floats, a
    fraction of the numpy calls)."""
    out: list[dict[str, Any]] = []
    todo: dict[int, list[tuple[int, Evidence, set]]] = {}     # id(library): runs
    libraries: dict[int, Library] = {}
    for i, result in enumerate(results):
        c = result.coordinator
        out.append({})
        if not perceives(c) or not result.world.start_cells:
            continue
        truth = set(result.world.start_cells)
        if getattr(c, "decider", None) is not None:
            est, name, p, _ = decision_verdict(c)
            out[i] = {"estimate_iou": iou(est, truth), "recognised": name, "p": p}
            continue
        w = result.world
        ev = Evidence(result.scenario.worldSize)
        for t in c.touches:
            ev.touch(t.sx, t.sy)
        if not ev.touched:
            out[i] = {"estimate_iou": 0.0, "recognised": None, "p": 0.0}
            continue
        mx = w.object_cells[0][0] - w.start_cells[0][0]
        my = w.object_cells[0][1] - w.start_cells[0][1]
        for x, y in zip(w.xs, w.ys):
            ev.free(fx.patch(x) - mx, fx.patch(y) - my)
        library = Library.of(result.scenario)
        libraries[id(library)] = library
        todo.setdefault(id(library), []).append((i, ev, truth))
    for key, runs in todo.items():
        recs = recognise_all([ev for _, ev, _ in runs], libraries[key])
        for (i, ev, truth), rec in zip(runs, recs):
            sure = rec.recognised(THRESHOLD)
            out[i] = {"estimate_iou": iou(estimate(ev, rec), truth),
                      "recognised": rec.best if sure else None, "p": round(rec.p, 6)}
    return out


def attach(engine: Any, **kw: Any) -> Perceiver | None:
    """A Perceiver on the engine when its behaviour perceives an object: its
    coordinator keeps touched segments (`touches`, each with sx, sy) of an
    object it tracks as it moves (`moved_x`), as the thesis's does; None
    otherwise (aggregate, whose stops are robots, not an object)."""
    if not perceives(engine.coordinator):
        return None
    return Perceiver(engine, **kw)
