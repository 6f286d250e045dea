"""The shape library: every candidate shape in its distinct orientations.

A shape is a set of cells up to translation. The grid has 8 rotations and
mirrors (the dihedral group of the square); a symmetric shape has fewer
distinct ones (the plus: 1, the bar: 2), and the prior spreads over the
distinct ones only, so a symmetric shape is not favoured by being counted
several times.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Iterable, Mapping

import numpy as np

from sim_backend import objects

Cell = tuple[int, int]

# the 8 maps of the dihedral group D4 as (a, b, c, d): (x, y) -> (a x + b y,
# c x + d y); orientations applies them spelt out (no call per cell)
MATRICES = ((1, 0, 0, 1), (0, -1, 1, 0), (-1, 0, 0, -1), (0, 1, -1, 0),
            (-1, 0, 0, 1), (0, 1, 1, 0), (1, 0, 0, -1), (0, -1, -1, 0))
# the same maps as functions of (x, y)
TRANSFORMS = tuple((lambda x, y, m=m: (m[0] * x + m[1] * y, m[2] * x + m[3] * y))
                   for m in MATRICES)
# the open-set hypothesis's name (recognise.py): "a shape not in the library"
UNKNOWN = objects.UNKNOWN


def normalise(cells: Iterable[Cell]) -> tuple[Cell, ...]:
    """Cells shifted so the smallest x and y are 0, sorted."""
    cs = set(cells)
    if not cs:
        raise ValueError("a shape needs at least one cell")
    xs, ys = zip(*cs)
    mx, my = min(xs), min(ys)
    return tuple(sorted([(x - mx, y - my) for x, y in cs]))


def orientations(cells: Iterable[Cell]) -> list[tuple[Cell, ...]]:
    """The distinct normalised images of a shape under the 8 grid maps, in
    the order of MATRICES (the identity first)."""
    base = list(cells)
    out: dict[tuple[Cell, ...], None] = {}
    for a, b, c, d in MATRICES:
        out.setdefault(normalise([(a * x + b * y, c * x + d * y) for x, y in base]), None)
    return list(out)


@dataclass(frozen=True)
class Pose:
    """One orientation of a shape: its cells from the placement origin, and
    the touchable ones (a free 4-neighbour: where a robot can touch it)."""
    shape: str
    index: int                     # which distinct orientation
    cells: tuple[Cell, ...]
    touchable: tuple[Cell, ...]
    width: int
    height: int

    def placed(self, ox: int, oy: int) -> set[Cell]:
        return {(ox + x, oy + y) for x, y in self.cells}


def _pose(name: str, index: int, cells: tuple[Cell, ...]) -> Pose:
    cs = set(cells)
    touch = tuple([(x, y) for x, y in cells
                   if (x + 1, y) not in cs or (x - 1, y) not in cs or (x, y + 1) not in cs
                   or (x, y - 1) not in cs])
    xs, ys = zip(*cells)
    return Pose(name, index, cells, touch, max(xs) + 1, max(ys) + 1)


@functools.lru_cache(maxsize=256)
def _shape(name: str, cells: tuple[Cell, ...]) -> tuple[Pose, ...]:
    """A shape's distinct poses, built once per process for each name and
    cells (a sweep builds a library per run; a Pose is immutable)."""
    return tuple(_pose(name, i, o) for i, o in enumerate(orientations(cells)))


@functools.lru_cache(maxsize=32)
def _masks(key: tuple) -> tuple[int, int, np.ndarray, np.ndarray]:
    poses = [p for name, cells in key for p in _shape(name, cells)]
    h = max(p.height for p in poses)
    w = max(p.width for p in poses)
    touch = np.zeros((h, w, len(poses)))
    cells = np.zeros((h, w, len(poses)))
    for i, p in enumerate(poses):
        for x, y in p.touchable:
            touch[y, x, i] = 1.0
        for x, y in p.cells:
            cells[y, x, i] = 1.0
    out = touch.reshape(h * w, len(poses)), cells.reshape(h * w, len(poses))
    for a in out:
        a.flags.writeable = False
    return h, w, out[0], out[1]


# Library.of's libraries by the shapes a scenario adds (read-only once built:
# a sweep's every run asks for its scenario's, and the poses took ~0.2 ms)
_OF: dict[tuple, "Library"] = {}


class Library:
    """Candidate shapes by name, each with its distinct orientations."""

    def __init__(self, shapes: Mapping[str, Iterable[Cell]]) -> None:
        if not shapes:
            raise ValueError("a shape library needs at least one shape")
        if UNKNOWN in shapes:
            raise ValueError(f"shape name {UNKNOWN!r} is taken: it names a shape not in the library")
        self.names = list(shapes)
        # what the library is, as a key: names and cells, in order
        self.key = tuple((name, tuple((x, y) for x, y in cells))
                         for name, cells in shapes.items())
        self.poses: dict[str, list[Pose]] = {name: list(_shape(name, cells))
                                             for name, cells in self.key}

    @classmethod
    def builtin(cls, known: Mapping[str, Iterable[Cell]] | None = None) -> "Library":
        """The built-in objects (sim_backend/objects.py) plus any shape a
        scenario marks as known (name -> cells), which replaces a built-in
        of the same name."""
        shapes: dict[str, Iterable[Cell]] = {n: objects.offsets(n) for n in objects.SHAPES}
        shapes.update(known or {})
        return cls(shapes)

    @classmethod
    def of(cls, sc, pieces: bool = False) -> "Library":
        """A scenario's library: the built-ins, the shapes its [[library]]
        tables name, and with pieces=True every object it draws (the host
        that fetches by shape knows them, perception/decide.py)."""
        known: dict[str, Iterable[Cell]] = {p.name: list(p.cells)
                                            for p in getattr(sc, "library", ())}
        if pieces:
            for p in sc.pieces():
                known.setdefault(p.name, list(p.cells))
        key = tuple((name, tuple(tuple(c) for c in cells)) for name, cells in known.items())
        lib = _OF.get(key)
        if lib is None or type(lib) is not cls:
            lib = _OF[key] = cls.builtin(known)
        return lib

    def masks(self) -> tuple[int, int, np.ndarray, np.ndarray]:
        """(H, W, touchable, cells): every pose as a column of an (H x W, poses)
        0/1 matrix, its cells from the top left of an H x W box (H, W: the
        tallest and widest pose), poses in the order of `names` and `poses`.
        Built once per process per library (read-only, shared)."""
        return _masks(self.key)

    def extent(self) -> int:
        """The largest width or height of any pose."""
        return max(max(p.width, p.height) for ps in self.poses.values() for p in ps)

