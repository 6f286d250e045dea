"""Recognition: a posterior over the library's shapes given the evidence.

The model (docs/perception.md, "Recognition", says why this one):
  - prior: uniform over shapes; within a shape uniform over its distinct
    orientations, and over the placements that fit the arena;
  - a touch: with probability 1 - eps_touch a segment drawn uniformly, without
    replacement, from the placed shape's touchable cells (those with a free
    4-neighbour); with probability eps_touch a false touch anywhere on the
    arena (1/A per cell). k touches on touchable cells of a shape with T of
    them: (1 - eps_touch)^k x (T - k)!/T! - the size principle: a small shape
    that explains the touches beats a large one that merely contains them;
  - a free cell (a distinct cell some robot occupied): likelihood eps_free if
    the placement covers it, 1 if not;
  - the posterior of a shape is the sum over its orientations and placements,
    normalised over the shapes. Placements that overlap no touched cell's
    bounding box explain no touch; they are summed in closed form (each has
    every touch false), so nothing is dropped from the normalisation.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from perception.evidence import FREE, OBJECT, Evidence
from perception.shapes import Library, Pose

EPS_TOUCH = 0.01     # a touch reported on a cell that is not the object's
EPS_FREE = 0.02      # a pose reported on a cell that is the object's
THRESHOLD = 0.95     # the posterior at which a shape counts as recognised

Cell = tuple[int, int]


@dataclass
class Recognition:
    """The posterior per shape and the MAP placement (None before a touch)."""
    posterior: dict[str, float]
    best: str | None = None
    p: float = 0.0
    map_cells: set[Cell] = field(default_factory=set)
    map_pose: Pose | None = None
    map_origin: Cell = (0, 0)

    def recognised(self, threshold: float = THRESHOLD) -> bool:
        return self.best is not None and self.p >= threshold


def _logsumexp(a: np.ndarray) -> float:
    if a.size == 0:
        return -math.inf
    m = float(a.max())
    if m == -math.inf:
        return m
    return m + math.log(float(np.exp(a - m).sum()))


def recognise(ev: Evidence, library: Library, eps_touch: float = EPS_TOUCH,
              eps_free: float = EPS_FREE) -> Recognition:
    """The posterior over the library's shapes given the evidence."""
    if not 0.0 < eps_touch < 1.0 or not 0.0 < eps_free < 1.0:
        raise ValueError(f"eps_touch {eps_touch}, eps_free {eps_free}: expected in (0, 1)")
    names = library.names
    if not ev.touched:
        return Recognition({n: 1.0 / len(names) for n in names})
    w, n = ev.w, ev.n
    area = n * n
    obj = (ev.grid == OBJECT).astype(np.int32)
    fre = (ev.grid == FREE).astype(np.int32)
    n_obj = len(ev.touched)
    xs = [c[0] for c in ev.touched]
    ys = [c[1] for c in ev.touched]
    xmin, xmax, ymin, ymax = min(xs), max(xs), min(ys), max(ys)
    log_false = math.log(eps_touch / area)
    log_true = math.log(1.0 - eps_touch)
    log_free = math.log(eps_free)
    maxt = max(len(p.touchable) for ps in library.poses.values() for p in ps)
    lfact = np.array([math.lgamma(k + 1) for k in range(maxt + 1)])
    per_shape: dict[str, float] = {}
    best_of: dict[str, tuple] = {}
    for name in names:
        poses = library.poses[name]
        terms = []
        best = (-math.inf, None, (0, 0))
        for pose in poses:
            fits = (n - pose.width + 1) * (n - pose.height + 1)
            if fits <= 0:
                continue
            prior = -math.log(len(poses)) - math.log(fits)
            # origins (patch coordinates) whose placement overlaps the touches' box
            ox0 = max(-w, xmin - pose.width + 1)
            ox1 = min(w - pose.width + 1, xmax)
            oy0 = max(-w, ymin - pose.height + 1)
            oy1 = min(w - pose.height + 1, ymax)
            inside = 0
            if ox0 <= ox1 and oy0 <= oy1:
                hx, hy = ox1 - ox0 + 1, oy1 - oy0 + 1
                inside = hx * hy
                gx, gy = ox0 + w, oy0 + w        # grid index of the first origin
                m_cells, m_touch = library.masks[(pose.shape, pose.index)]
                ys_, xs_ = slice(gy, gy + hy + pose.height - 1), slice(gx, gx + hx + pose.width - 1)
                win_o = sliding_window_view(obj[ys_, xs_], m_cells.shape)   # (hy, hx, h, w)
                win_f = sliding_window_view(fre[ys_, xs_], m_cells.shape)
                on_t = np.einsum("ijkl,kl->ij", win_o, m_touch)
                on_f = np.einsum("ijkl,kl->ij", win_f, m_cells)
                t = len(pose.touchable)
                k = np.minimum(on_t, t)
                ll = (k * log_true - (lfact[t] - lfact[t - k]) + (n_obj - k) * log_false
                      + on_f * log_free + prior)
                terms.append(_logsumexp(ll))
                j = int(np.argmax(ll))
                if float(ll.flat[j]) > best[0]:
                    best = (float(ll.flat[j]), pose, (ox0 + j % hx, oy0 + j // hx))
            rest = fits - inside
            if rest > 0:   # placements away from every touch: all touches false
                terms.append(prior + math.log(rest) + n_obj * log_false)
        per_shape[name] = _logsumexp(np.array(terms)) if terms else -math.inf
        best_of[name] = best
    total = _logsumexp(np.array(list(per_shape.values())))
    post = {k: math.exp(v - total) for k, v in per_shape.items()}
    top = max(post, key=post.get)
    _, pose, origin = best_of[top]      # the MAP placement of the most probable shape
    cells = pose.placed(*origin) if pose is not None else set()
    return Recognition(post, top, post[top], cells, pose, origin)


def estimate(ev: Evidence, rec: Recognition, threshold: float = THRESHOLD) -> set[Cell]:
    """The best shape estimate: the MAP placement of a recognised shape,
    otherwise the touched cells' hull minus every known-free cell."""
    if rec.recognised(threshold) and rec.map_pose is not None:
        return set(rec.map_cells)
    return ev.hull_estimate()
