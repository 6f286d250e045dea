"""Object shapes: the four of the thesis's DrawObject, and a few more.

Each shape is a list of patch offsets from the object's anchor (objX, objY),
which CreateWorld draws as `random 10` on each axis.
"""

from __future__ import annotations


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
