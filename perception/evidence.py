"""The evidence grid: every arena cell is known object, known free or unknown.

Cells are kept in the object's frame, the frame the host stores touches in
(the object where it stood when it was first touched): a pose reported after
the object moved `(mx, my)` patches is shifted back by that much. So the
evidence of the search phase and of the transport add up in one grid.

Sources:
  touch(x, y)   a touched segment (the host accepted the report): object.
  free(x, y)    a cell a robot occupied (its pose from a HEARTBEAT on a link,
                or every tick in simulation): free.

A cell is never both. A touch is authoritative (the coordinator checked the
report against the object), so a touch on a cell seen free turns it into
object and counts a conflict; a free observation of a touched cell is
ignored and counted (a robot started on the object, or its pose was taken a
tick before the host learnt that the object moved).
"""

from __future__ import annotations

import functools
from typing import Iterable

import numpy as np

from firmware_logic import perception

UNKNOWN = 0
OBJECT = 1
FREE = 2

Cell = tuple[int, int]


class Evidence:
    """The evidence about one object on an arena from -w..w on both axes."""

    def __init__(self, world_size: int) -> None:
        if world_size < 1:
            raise ValueError(f"world_size: {world_size}; expected >= 1")
        self.w = world_size
        self.n = 2 * world_size + 1
        self.grid = np.zeros((self.n, self.n), dtype=np.int8)   # row = y + w
        self.touched: list[Cell] = []        # object cells, in order of touch
        self.free_cells = 0
        self.conflicts = 0                   # free seen on object, or object on free
        self.version = 0                     # bumps whenever the grid changes
        self._estimate: tuple[int, set[Cell]] = (-1, set())   # hull_estimate at a version

    def inside(self, x: int, y: int) -> bool:
        return -self.w <= x <= self.w and -self.w <= y <= self.w

    def at(self, x: int, y: int) -> int:
        return int(self.grid[y + self.w, x + self.w]) if self.inside(x, y) else UNKNOWN

    def touch(self, x: int, y: int) -> bool:
        """A touched segment; True if it was news."""
        if not self.inside(x, y):
            return False
        v = self.grid[y + self.w, x + self.w]
        if v == OBJECT:
            return False
        if v == FREE:
            self.conflicts += 1
            self.free_cells -= 1
        self.grid[y + self.w, x + self.w] = OBJECT
        self.touched.append((x, y))
        self.version += 1
        return True

    def free(self, x: int, y: int) -> bool:
        """A cell a robot occupied; True if it was news."""
        if not self.inside(x, y):
            return False
        v = self.grid[y + self.w, x + self.w]
        if v == OBJECT:
            self.conflicts += 1
            return False
        if v == FREE:
            return False
        self.grid[y + self.w, x + self.w] = FREE
        self.free_cells += 1
        self.version += 1
        return True

    def heartbeat(self, fields: tuple, moved: Cell = (0, 0)) -> bool:
        """A HEARTBEAT's pose (fields: state, x, y in Q8 patches, heading,
        step) as free evidence, shifted into the object's frame."""
        x = (fields[1] + 128) >> 8
        y = (fields[2] + 128) >> 8
        return self.free(x - moved[0], y - moved[1])

    # -- views -------------------------------------------------------------

    def object_cells(self) -> set[Cell]:
        return set(self.touched)

    def free_set(self) -> set[Cell]:
        ys, xs = np.nonzero(self.grid == FREE)
        return {(int(x) - self.w, int(y) - self.w) for x, y in zip(xs, ys)}

    def hull_cells(self) -> set[Cell]:
        """The thesis-style outline: touched cells and every cell inside their hull."""
        return outline(self.touched)

    def hull_estimate(self) -> set[Cell]:
        """The estimate without a library: the hull minus every known-free
        cell (kept until the grid changes: recognise and estimate both ask)."""
        if self._estimate[0] != self.version:
            hull = self.hull_cells()
            if hull:
                xs = [c[0] for c in hull]
                ys = [c[1] for c in hull]
                hull -= self.free_in(min(xs), max(xs), min(ys), max(ys))
            self._estimate = (self.version, hull)
        return set(self._estimate[1])

    def free_in(self, x0: int, x1: int, y0: int, y1: int) -> set[Cell]:
        """The known-free cells of the box x0..x1, y0..y1 (a set to test
        cells against: a grid read per cell costs more than the set)."""
        w = self.w
        ax, ay = max(x0, -w), max(y0, -w)
        ys, xs = np.nonzero(self.grid[ay + w:min(y1, w) + w + 1, ax + w:min(x1, w) + w + 1] == FREE)
        return set(zip((xs + ax).tolist(), (ys + ay).tolist()))

    def joined(self) -> set[Cell]:
        """The smallest-looking shape the touches allow: the touched cells
        joined into one 4-connected piece by shortest paths that avoid
        known-free cells (a shape is one piece), within the touches' box
        widened by 2. The open-set posterior's leanest hypothesis."""
        if not self.touched:
            return set()
        if connected(self.touched):
            # every search below would stop on a touch next to the shape
            return set(self.touched)
        xs = [c[0] for c in self.touched]
        ys = [c[1] for c in self.touched]
        x0, x1, y0, y1 = min(xs) - 2, max(xs) + 2, min(ys) - 2, max(ys) + 2
        free = self.free_in(x0, x1, y0, y1)
        shape = {self.touched[0]}
        rest = set(self.touched[1:])
        while rest:
            prev: dict[Cell, Cell | None] = {c: None for c in shape}
            frontier = list(shape)
            hit = None
            while frontier and hit is None:
                nxt = []
                for x, y in frontier:
                    for a, b in ((1, 0), (-1, 0), (0, 1), (0, -1)):
                        c = (x + a, y + b)
                        if c in prev or not (x0 <= c[0] <= x1 and y0 <= c[1] <= y1) \
                                or c in free:
                            continue
                        prev[c] = (x, y)
                        if c in rest:
                            hit = c
                            break
                        nxt.append(c)
                    if hit is not None:
                        break
                frontier = nxt
            if hit is None:             # walled off by free cells: take the touches as they are
                return shape | rest
            back: Cell | None = hit
            while back is not None and back not in shape:
                shape.add(back)
                back = prev[back]
            shape |= {t for t in rest if t in shape}
            rest -= shape
        return shape

    def uncertainty(self) -> dict[str, int]:
        """Cells inside the hull: known object, known free, unknown."""
        counts = {"object": 0, "free": 0, "unknown": 0}
        for c in self.hull_cells():
            v = self.at(*c)
            counts["object" if v == OBJECT else "free" if v == FREE else "unknown"] += 1
        return counts


def connected(cells: Iterable[Cell]) -> bool:
    """Whether the cells form one 4-connected piece (True for none)."""
    rest = set(cells)
    if not rest:
        return True
    todo = [rest.pop()]
    while todo:
        x, y = todo.pop()
        for c in ((x + 1, y), (x - 1, y), (x, y + 1), (x, y - 1)):
            if c in rest:
                rest.remove(c)
                todo.append(c)
    return not rest


def outline(cells: Iterable[Cell]) -> set[Cell]:
    """The touched cells' outline, perception.outline_cells (a new set):
    computed once per process for each set of cells, as a run's summary
    asks for it twice (shape_iou from the coordinator's segments, the
    recognition's hull from the evidence's touches); a batch's summaries
    ask a chunk's recognitions first (soa.run_batch), so the cache holds
    more than a chunk (sweep.MAX_CHUNK) of runs."""
    return set(_outline(frozenset(cells)))


@functools.lru_cache(maxsize=1024)
def _outline(cells: frozenset[Cell]) -> frozenset[Cell]:
    return frozenset(perception.outline_cells(cells))


def iou(a: Iterable[Cell], b: Iterable[Cell]) -> float:
    """IoU of two cell sets, rounded to 6 places as summaries have it."""
    inter, union = perception.iou_counts(a, b)
    return round(inter / union, 6) if union else 0.0

