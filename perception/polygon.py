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
    points; none when fewer than three distinct points span an area."""
    poly = polygon(points)
    if len(poly) < 4:
        return set()
    xs = [p[0] for p in poly]
    ys = [p[1] for p in poly]
    return {(x, y) for x in range(min(xs) + 1, max(xs)) for y in range(min(ys) + 1, max(ys))
            if strictly_inside(poly, (x, y))}


def polygon_iou(points: Iterable[Cell], cells: Iterable[Cell]) -> float:
    """IoU of the cells the points' polygon encloses with `cells`, rounded to
    6 places as summaries have it; 0.0 when both are empty."""
    a = enclosed_cells(points)
    b = set(cells)
    union = len(a | b)
    return round(len(a & b) / union, 6) if union else 0.0
