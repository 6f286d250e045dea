"""Object shapes: the four of the thesis's DrawObject, and a few more.

Each shape is a list of patch offsets from the object's anchor (objX, objY),
which CreateWorld draws as `random 10` on each axis.
"""

from __future__ import annotations

from dataclasses import dataclass


def _bar() -> list[tuple[int, int]]:          # DrawObject object = 1
    out = []
    for a in range(1, 9):
        out += [(a, 0), (a, 1)]
    return out


def _l() -> list[tuple[int, int]]:            # object = 2
    out = []
    for a in range(1, 9):
        out += [(a, 0), (1, a)]
    return out


def _cross() -> list[tuple[int, int]]:        # object = 3, the thesis's '+'
    out = [(0, 0)]
    for a in range(1, 9):
        out += [(a, 0), (6, 6 - a)]
    return out


def _x() -> list[tuple[int, int]]:            # object = 4
    out = [(0, 0)]
    for a in range(1, 9):
        out += [(a, a), (a, 8 - a)]
    return out


def _plus() -> list[tuple[int, int]]:
    return [(a, 4) for a in range(9)] + [(4, a) for a in range(9)]


def _t() -> list[tuple[int, int]]:
    return [(a, 8) for a in range(9)] + [(4, a) for a in range(8)]


def _square() -> list[tuple[int, int]]:
    return [(x, y) for x in range(1, 5) for y in range(1, 5)]


# `object = "none"`: an arena with no object (a behaviour that carries nothing)
NONE = "none"
# the name the host's recogniser reports a shape by when it is none of the
# shapes it knows (perception/recognise.py); no object or library shape may take it
UNKNOWN = "unknown"

SHAPES = {
    "bar": _bar,
    "L": _l,
    "cross": _cross,
    "X": _x,
    "plus": _plus,
    "T": _t,
    "square": _square,
}
THESIS_NUMBERS = {1: "bar", 2: "L", 3: "cross", 4: "X"}


def offsets(name: str) -> list[tuple[int, int]]:
    """Distinct offsets of a shape, in drawing order."""
    seen: dict[tuple[int, int], None] = {}
    for c in SHAPES[name]():
        seen.setdefault(c, None)
    return list(seen)


def cells(name: str, ox: int, oy: int) -> list[tuple[int, int]]:
    return [(ox + x, oy + y) for x, y in offsets(name)]


def touchable(name: str) -> int:
    """Segments a robot can reach: those with a free 4-neighbour."""
    cs = set(offsets(name))
    return sum(1 for (x, y) in cs
               if any((x + ddx, y + ddy) not in cs
                      for ddx, ddy in ((1, 0), (-1, 0), (0, 1), (0, -1))))


# -- objects and obstacles as the user draws them (docs/scenarios.md) -----------

ART_CELL = "#"
ART_EMPTY = ". "


def art_cells(art: str) -> list[tuple[int, int]]:
    """Cells of an art block, rows top to bottom, relative to its lower-left
    corner (the lowest row is y 0, the leftmost column x 0). '#' is a cell,
    '.' or ' ' empty; anything else raises ValueError naming it."""
    rows = [r for r in art.split("\n")]
    while rows and not rows[0].strip():
        rows.pop(0)
    while rows and not rows[-1].strip():
        rows.pop()
    out = []
    for y, row in enumerate(reversed(rows)):
        for x, ch in enumerate(row):
            if ch == ART_CELL:
                out.append((x, y))
            elif ch not in ART_EMPTY:
                raise ValueError(f"character {ch!r} in row {len(rows) - y}; expected "
                                 f"'{ART_CELL}' for a cell, '.' or ' ' for none")
    return out


def to_art(cells: list[tuple[int, int]]) -> str:
    """The art block of a set of cells (the inverse of art_cells, up to a shift)."""
    cs = set(cells)
    xs = [x for x, _ in cs]
    ys = [y for _, y in cs]
    rows = []
    for y in range(max(ys), min(ys) - 1, -1):
        rows.append("".join(ART_CELL if (x, y) in cs else "." for x in range(min(xs),
                                                                               max(xs) + 1)))
    return "\n".join(rows)


def art(name: str) -> str:
    """A built-in shape as named art (`touchswarm scenarios` prints each)."""
    return to_art(offsets(name))


@dataclass(frozen=True)
class Piece:
    """One object or obstacle of a scenario, as validated.

    cells are relative to `at` (an object's anchor, CreateWorld's objX, objY);
    at None: drawn as CreateWorld draws it (`random 10` on each axis). weight
    is resolved (density x cells when the table gave a density)."""
    name: str
    cells: tuple[tuple[int, int], ...]
    at: tuple[int, int] | None = None
    weight: float = 0.0
    density: float | None = None
    target: bool = False

    def __repr__(self) -> str:      # one CSV cell per piece in a sweep's rows
        return f"{self.name}@{list(self.at) if self.at else 'random10'}:{len(self.cells)}cells"

    def placed(self, ax: int, ay: int) -> list[tuple[int, int]]:
        return [(ax + x, ay + y) for x, y in self.cells]


def surround(cells: list[tuple[int, int]], free) -> int:
    """How many robots can hold the object at once (thesis 6.1.5, the limit
    to the robots that can surround it): at most one per reachable segment (a
    segment with a free 4-neighbour, where a robot can stand and claim it) and
    one per free patch touching the object. free(x, y): a robot may stand there."""
    cs = set(cells)
    step4 = ((1, 0), (-1, 0), (0, 1), (0, -1))
    reach = sum(1 for (x, y) in cs
                if any((x + a, y + b) not in cs and free(x + a, y + b) for a, b in step4))
    ring = set()
    for x, y in cs:
        for a in (-1, 0, 1):
            for b in (-1, 0, 1):
                p = (x + a, y + b)
                if p not in cs and free(*p):
                    ring.add(p)
    return min(reach, len(ring))
