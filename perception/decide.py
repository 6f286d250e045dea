"""The host's decider for a recognising coordinator: is a
cluster of touches the target, and how sure is the host?

The thesis coordinator (firmware_logic/behaviours/thesis/recognising.py) is
subset code and imports nothing from here; the host injects a `Decider` as
`coordinator.decider`. Called with a cluster's touched cells and the cells
robots reported standing on (HEARTBEAT poses), it builds that cluster's
evidence, runs the Bayesian recogniser (recognise.py) over the library and
answers the posterior of the target's shape, in per mille.

The library is the built-in shapes plus every object the scenario draws
(the shapes the host knows of, each under its name); the target is known by
its shape (the mission says what to fetch), never by its place. Library
entries with the target's shape (in any of its 8 orientations) all count
for it, so a decoy drawn in the same shape as the target cannot be told
apart, and the posterior says so.

The prior. The recogniser's prior is uniform over the library's shapes, so
the target's shape starts at 1/8 or so, and a few collinear touches on an
arm of the X make the shorter diagonal decoy far likelier by the size
principle: the X's holders were released as decoys again and again. But
the host knows more than the library: the world holds one target among
the objects it mapped. So the decider moves the target's prior odds to
1 : (n - 1) for n objects (n at least 2: the host never assumes a lone
object must be the target), i.e. it multiplies the posterior odds by
(1 / (n - 1)) / (prior share / (1 - prior share)). A cluster is then
called a decoy only when its touches rule the target out more firmly.
"""

from __future__ import annotations

from typing import Any, Iterable, NamedTuple

from perception import DEBUG, detail
from perception.evidence import Evidence
from perception.recognise import estimate, recognise
from perception.shapes import Library, orientations


Cell = tuple[int, int]


def library_for(sc: Any) -> tuple[Library, list[str]]:
    """The scenario's library and the names of the entries that are the target's shape."""
    pieces = sc.pieces()
    lib = Library.of(sc, pieces=True)
    target = set(orientations(pieces[0].cells))
    names = [n for n in lib.names
             if set(tuple(p.cells) for p in lib.poses[n]) == target]
    return lib, names


class Call(NamedTuple):
    """One verdict: the cluster's evidence, the permille answered, the
    posterior behind it and the estimate it gives."""
    ev: Evidence
    permille: int
    rec: Any
    estimate: set


def key(cells: Iterable[Cell]) -> tuple[Cell, ...]:
    return tuple(sorted(set((int(x), int(y)) for x, y in cells)))


class Decider:
    """decider(cells, free) -> permille that the cluster is the target.

    Every call is kept (`answers`, by the cluster's cells), so the run's
    perception reports the very verdict the decision used (one verdict per
    run: `verdict(cells)`)."""

    def __init__(self, sc: Any) -> None:
        self.w = sc.worldSize
        self.library, self.target = library_for(sc)
        self.target_name = sc.pieces()[0].name
        self.calls = 0
        self.answers: dict[tuple[Cell, ...], Call] = {}
        self.best: Call | None = None       # the call with the highest permille so far
        n = max(2, len(sc.pieces()))
        share = len(self.target) / len(self.library.names)
        # prior odds of the target: the scenario's 1 : (n - 1) over the library's
        self.odds = (1 / (n - 1)) / (share / (1 - share))

    def __call__(self, cells: Iterable[Cell], free: Iterable[Cell] = ()) -> int:
        cells = list(cells)
        ev = Evidence(self.w)
        for x, y in cells:
            ev.touch(x, y)
        for c in free:
            ev.free(*c)
        rec = recognise(ev, self.library)
        self.calls += 1
        p = sum(rec.posterior[n] for n in self.target)
        if p >= 1.0:
            permille = 1000
        else:
            odds = p / (1 - p) * self.odds
            q = odds / (1 + odds)
            detail(__name__, DEBUG, "cluster %s: target p %.3f, with the scenario's prior %.3f "
                   "(best %s %.3f)", sorted(ev.touched), p, q, rec.best, rec.p)
            permille = int(q * 1000)
        call = Call(ev, permille, rec, estimate(ev, rec))
        self.answers[key(cells)] = call
        if self.best is None or permille >= self.best.permille:
            self.best = call
        return permille

    def verdict(self, cells: Iterable[Cell]) -> Call | None:
        """The call made on exactly these cells, if any."""
        return self.answers.get(key(cells))


def equip(coordinator: Any, sc: Any) -> Any:
    """Give a coordinator that wants one (its wants_decider()) a decider;
    a no-op otherwise."""
    from sim_backend.coordinator import Recognising, has
    if has(coordinator, Recognising) and coordinator.wants_decider():
        coordinator.decider = Decider(sc)
    return coordinator
