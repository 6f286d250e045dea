"""Shape perceived from touch coordinates: touched segments and an outline.

Pure integer geometry on patch coordinates, so the host processes of every
link reuse it unchanged and it could run on a board as well.
"""

# host-side helpers: portable, but allowed to allocate
SUBSET_SETUP = ("convex_hull", "inside_hull", "outline_cells", "iou_counts")


def convex_hull(points):
    """Convex hull (counter-clockwise, no repeated point) of integer points."""
    pts = sorted(set(points))
    if len(pts) <= 2:
        return pts
    lower = []
    for p in pts:
        while len(lower) >= 2 and _cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper = []
    i = len(pts) - 1
    while i >= 0:
        p = pts[i]
        while len(upper) >= 2 and _cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
        i -= 1
    return lower[:-1] + upper[:-1]


def _cross(o, a, b):
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def inside_hull(hull, p):
    """True if p lies inside or on the convex polygon `hull` (CCW)."""
    n = len(hull)
    if n == 0:
        return False
    if n == 1:
        return p == hull[0]
    if n == 2:
        a = hull[0]
        b = hull[1]
        if _cross(a, b, p) != 0:
            return False
        return (min(a[0], b[0]) <= p[0] <= max(a[0], b[0])
                and min(a[1], b[1]) <= p[1] <= max(a[1], b[1]))
    i = 0
    while i < n:
        if _cross(hull[i], hull[(i + 1) % n], p) < 0:
            return False
        i += 1
    return True


def outline_cells(segments):
    """Cells the perceived shape covers: the touched segments plus every
    patch whose centre lies inside their convex hull."""
    segs = set(segments)
    hull = convex_hull(segs)
    if len(hull) < 3:
        return segs
    xs = []
    ys = []
    for p in hull:
        xs.append(p[0])
        ys.append(p[1])
    cells = set(segs)
    for x in range(min(xs), max(xs) + 1):
        for y in range(min(ys), max(ys) + 1):
            if inside_hull(hull, (x, y)):
                cells.add((x, y))
    return cells


def iou_counts(a, b):
    """(intersection, union) sizes of two cell sets; IoU = inter / union."""
    a = set(a)
    b = set(b)
    return len(a & b), len(a | b)
