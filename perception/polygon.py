"""The polygon through the holders' rounded positions and the cells it
encloses: a perceived shape read the way a reader of the touch points draws
it (docs/perception.md, "The holder polygon").

The holders of an object stand on the patches next to it, so the object is
what their polygon encloses: the patches whose centres lie strictly inside
it (a patch on its boundary is a holder's own patch or lies between two
holders, outside the object). Its IoU with the object's cells is
`polygon_iou`, a measure a behaviour offers by declaring it (spec.MEASURES).

Plain integer geometry, no imports: every point is a patch (x, y).
"""

from __future__ import annotations

import math
from typing import Iterable, Sequence

Cell = tuple[int, int]


def polygon(points: Iterable[Cell]) -> list[Cell]:
    """The closed polygon through the points (duplicates dropped) in angle
    order about their centroid, the first point repeated at the end: the
    outline a reader draws through the holders' positions. One or no point:
    the points themselves, not closed."""
    pts = sorted(set((int(x), int(y)) for x, y in points))
    if len(pts) < 2:
        return pts
    mx = sum(x for x, _ in pts) / len(pts)
    my = sum(y for _, y in pts) / len(pts)
    pts.sort(key=lambda p: (math.atan2(p[1] - my, p[0] - mx), p))
    return pts + [pts[0]]


def strictly_inside(poly: Sequence[Cell], p: Cell) -> bool:
    """True if p lies inside the closed polygon `poly` (even-odd rule) and not
    on its boundary; exact, in integers."""
    x, y = p
    inside = False
    for i in range(len(poly) - 1):
        (x1, y1), (x2, y2) = poly[i], poly[i + 1]
        cross = (x2 - x1) * (y - y1) - (y2 - y1) * (x - x1)
        if cross == 0 and min(x1, x2) <= x <= max(x1, x2) and min(y1, y2) <= y <= max(y1, y2):
            return False
        if (y1 > y) != (y2 > y):
            # the edge crosses the horizontal through p right of p
            if (cross > 0) == (y2 > y1):
                inside = not inside
    return inside


def enclosed_cells(points: Iterable[Cell]) -> set[Cell]:
    """The patches whose centres lie strictly inside the polygon through the
    points (as `strictly_inside` says, row by row: the even-odd intervals
    between a row's edge crossings, less the boundary's points); none when
    fewer than three distinct points span an area."""
    poly = polygon(points)
    if len(poly) < 4:
        return set()
    edges = list(zip(poly, poly[1:]))
    ys = [p[1] for p in poly]
    out: set[Cell] = set()
    for y in range(min(ys) + 1, max(ys)):
        cuts = []                       # crossings x = num / den, den > 0
        edge_points = {p[0] for p in poly[:-1] if p[1] == y}
        for (x1, y1), (x2, y2) in edges:
            if (y1 > y) != (y2 > y):
                num, den = x1 * (y2 - y1) + (y - y1) * (x2 - x1), y2 - y1
                cuts.append((num, den) if den > 0 else (-num, -den))
            elif y1 == y2 == y:
                edge_points.update(range(min(x1, x2), max(x1, x2) + 1))
        cuts.sort(key=lambda c: c[0] / c[1])
        for (n0, d0), (n1, d1) in zip(cuts[::2], cuts[1::2]):
            # the integers x with n0/d0 < x < n1/d1
            for x in range(n0 // d0 + 1, -(-n1 // d1)):
                if x not in edge_points:
                    out.add((x, y))
    return out


def polygon_iou(points: Iterable[Cell], cells: Iterable[Cell]) -> float:
    """IoU of the cells the points' polygon encloses with `cells`, rounded to
    6 places as summaries have it; 0.0 when both are empty."""
    a = enclosed_cells(points)
    b = set(cells)
    union = len(a | b)
    return round(len(a & b) / union, 6) if union else 0.0
