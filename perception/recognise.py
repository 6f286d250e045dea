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
  - open set: one more hypothesis, UNKNOWN, "a shape not in the
    library", with prior P_OPEN. Its shape is the evidence's own outline E
    (the touches' hull minus known-free cells, `Evidence.hull_estimate`),
    priced by a prior over all polyominoes of |E| cells (about 4.06^n / n
    of them, so each costs ~1.4 nats a cell) and a uniform placement; the
    touches are drawn from E's touchable cells by the same size principle,
    and no free cell lies in E. A library shape that fits the evidence
    beats it by its far smaller prior cost; one that must cover free cells
    or leave touches unexplained loses to it.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from typing import Iterator, Sequence

import numpy as np

from perception.evidence import FREE, OBJECT, Evidence
from perception.shapes import UNKNOWN, Library, Pose, _masks

EPS_TOUCH = 0.01     # a touch reported on a cell that is not the object's
EPS_FREE = 0.02      # a pose reported on a cell that is the object's
THRESHOLD = 0.95     # the posterior at which a shape counts as recognised
P_OPEN = 0.5         # its prior; the library's shapes share the rest
# fixed polyominoes of n cells: about POLY_C * POLY_GROWTH^n / n (Jensen 2001)
POLY_C, POLY_GROWTH = 0.3169, 4.0626
POLY_SIZES = 64      # the prior over an unknown shape's size: uniform on 1..POLY_SIZES

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

    @property
    def unknown(self) -> bool:
        """The most probable hypothesis is "not in the library"."""
        return self.best == UNKNOWN

    def recognised(self, threshold: float = THRESHOLD) -> bool:
        return self.best is not None and self.p >= threshold


def touchable(cells: set[Cell]) -> int:
    """Cells of a shape with a 4-neighbour outside it."""
    n = 0
    for x, y in cells:      # spelt out: a generator per cell cost most of a summary's share
        if ((x + 1, y) not in cells or (x - 1, y) not in cells or (x, y + 1) not in cells
                or (x, y - 1) not in cells):
            n += 1
    return n


def log_polyomino_prior(n: int) -> float:
    """log P(one particular n-cell shape) under the open-set prior: a size
    uniform on 1..POLY_SIZES, then any of the ~POLY_C x POLY_GROWTH^n / n
    fixed polyominoes of that size."""
    return -math.log(POLY_SIZES) - (math.log(POLY_C) + n * math.log(POLY_GROWTH) - math.log(n))


def priors(library: Library, p_open: float) -> dict[str, float]:
    """The prior of every hypothesis: the library's shapes share 1 - p_open
    uniformly, UNKNOWN has p_open (0: a closed library)."""
    if not 0.0 <= p_open < 1.0:
        raise ValueError(f"p_open {p_open}: expected in [0, 1)")
    out = {n: (1.0 - p_open) / len(library.names) for n in library.names}
    if p_open > 0.0:
        out[UNKNOWN] = p_open
    return out


def recognise(ev: Evidence, library: Library, eps_touch: float = EPS_TOUCH,
              eps_free: float = EPS_FREE, p_open: float = P_OPEN) -> Recognition:
    """The posterior over the library's shapes and UNKNOWN given the evidence."""
    return recognise_all([ev], library, eps_touch, eps_free, p_open)[0]


def recognise_all(evs: Sequence[Evidence], library: Library, eps_touch: float = EPS_TOUCH,
                  eps_free: float = EPS_FREE, p_open: float = P_OPEN) -> list[Recognition]:
    """recognise(ev, library) of every evidence, the same floats, with the
    numpy calls on small arrays made once for all of them (a sweep's
    chunk of runs: those calls, not their arithmetic, cost most of a
    recognition). Each row of a batched call is one evidence's own array
    of the same length, reduced along its own row, as recognise's was."""
    if not 0.0 < eps_touch < 1.0 or not 0.0 < eps_free < 1.0:
        raise ValueError(f"eps_touch {eps_touch}, eps_free {eps_free}: expected in (0, 1)")
    prior = priors(library, p_open)
    todo = [_Posterior(ev, library, eps_touch, eps_free) for ev in evs if ev.touched]
    if todo:
        _near_all(todo, library)
        # the shapes' sums and UNKNOWN's, then their normalisation
        lses = _logsumexp_all([a for r in todo for a in r.terms(prior)])
        k = 0
        for r in todo:
            k = r.shape_logs(prior, lses, k)
        totals = _logsumexp_all([list(r.per_shape.values()) for r in todo])
    out: list[Recognition] = []
    k = 0
    for ev in evs:
        if not ev.touched:
            out.append(Recognition(dict(prior)))
        else:
            out.append(todo[k].result(totals[k]))
            k += 1
    return out


class _Posterior:
    """One evidence's recognition, in the stages recognise_all runs for a
    batch at once."""

    def __init__(self, ev: Evidence, library: Library, eps_touch: float,
                 eps_free: float) -> None:
        self.ev = ev
        w, n = ev.w, ev.n
        self.n_obj = n_obj = len(ev.touched)
        xs = [c[0] for c in ev.touched]
        ys = [c[1] for c in ev.touched]
        self.box = xmin, xmax, ymin, ymax = min(xs), max(xs), min(ys), max(ys)
        self.log_false = math.log(eps_touch / (n * n))
        self.log_true = math.log(1.0 - eps_touch)
        # for every origin near the touches and every pose: touched cells on the
        # pose's touchable cells, free cells on its cells (integer counts as
        # one exact product of 0/1 matrices; beyond the arena unknown)
        mh, mw, _, _ = library.masks()
        self.x0, self.y0 = x0, y0 = max(-w, xmin - mw + 1), max(-w, ymin - mh + 1)
        self.rw, self.rh = rw, rh = xmax - x0 + 1, ymax - y0 + 1
        part = ev.grid[y0 + w:y0 + w + rh + mh - 1, x0 + w:x0 + w + rw + mw - 1]
        pad = np.zeros((rh + mh - 1, rw + mw - 1), dtype=part.dtype)
        pad[:part.shape[0], :part.shape[1]] = part
        # every origin's window (a strided view: sliding_window_view's checks
        # cost more than the product on a sweep's small boxes)
        self.win = np.ndarray((rh, rw, mh, mw), pad.dtype, pad, 0,
                              pad.strides * 2).reshape(rh * rw, mh * mw)
        (self.ordered, self.fits, self.place, self.far, self.table,
         self.boxes) = _table(library.key, n, eps_touch, eps_free, n_obj)
        self.near: dict[int, tuple[float, float, Cell, int]] = {}

    def placements(self, at: np.ndarray) -> None:
        """Every pose's log-likelihood at every origin, from the flat
        table indices `at` of this evidence's windows."""
        self.ll_all = self.table.reshape(-1).take(at.astype(np.intp)).T.reshape(
            -1, self.rh, self.rw)                                      # (poses, rh, rw)

    def near_boxes(self) -> Iterator[tuple[tuple[int, int, int], np.ndarray, tuple]]:
        """Every pose's placements that overlap the touches' box, one array
        per pose box: origins (patch coordinates) that depend on the pose
        only through its box, so the poses of one box are summed at once.
        Yields (what the rows' length depends on, the rows, what `reduced`
        needs back)."""
        w = self.ev.w
        xmin, xmax, ymin, ymax = self.box
        x0, y0 = self.x0, self.y0
        for b, ((bw, bh), cols, columns, rows) in enumerate(self.boxes):
            ox0, ox1 = max(-w, xmin - bw + 1), min(w - bw + 1, xmax)
            oy0, oy1 = max(-w, ymin - bh + 1), min(w - bh + 1, ymax)
            if ox0 > ox1 or oy0 > oy1:
                continue
            hx, hy = ox1 - ox0 + 1, oy1 - oy0 + 1
            ll = self.ll_all[cols, oy0 - y0:oy0 - y0 + hy, ox0 - x0:ox0 - x0 + hx]
            yield (b, hx, hy), ll.reshape(len(rows), -1), (columns, ox0, oy0, hx, hy)

    def reduced(self, key: tuple, j: list[int], top: list[float], sums: list[float]) -> None:
        """A box's rows reduced: each row's argmax, max and sum of exp(row - max)."""
        columns, ox0, oy0, hx, hy = key
        for column, jj, tt, ss in zip(columns, j, top, sums):
            self.near[column] = (tt + math.log(ss), tt, (ox0 + jj % hx, oy0 + jj // hx), hx * hy)

    def terms(self, prior: dict[str, float]) -> list[list[float]]:
        """The lists whose logsumexp shape_logs needs: each shape's terms
        (the placements near the touches, the rest in closed form), then,
        with the open set, UNKNOWN's two."""
        names = [name for name in prior if name != UNKNOWN]
        near, fits, far, place = self.near, self.fits, self.far, self.place
        n_obj, log_false = self.n_obj, self.log_false
        best_of: dict[str, tuple] = {name: (-math.inf, None, (0, 0)) for name in names}
        terms: dict[str, list[float]] = {name: [] for name in names}
        for column, (name, pose) in enumerate(self.ordered):
            if fits[column] <= 0:
                continue
            inside = 0
            if column in near:
                lse, top1, origin1, inside = near[column]
                terms[name].append(lse)
                if top1 > best_of[name][0]:
                    best_of[name] = (top1, pose, origin1)
            rest = fits[column] - inside
            if rest == fits[column]:
                terms[name].append(far[column])
            elif rest > 0:   # placements away from every touch: all touches false
                terms[name].append(place[column] + math.log(rest) + n_obj * log_false)
        self.best_of = best_of
        self.named = [name for name in names if terms[name]]
        out = [terms[name] for name in self.named]
        self.outline: set[Cell] = set()
        if UNKNOWN in prior:
            ev = self.ev
            self.outline = ev.hull_estimate()
            # the sum over every shape not in the library, bounded below by two
            # of its terms: the outline itself and the leanest shape the
            # touches allow (their cells joined into one piece)
            out.append([_free_form(cs, ev.n, n_obj, self.log_true)
                        for cs in (self.outline, ev.joined())])
        return out

    def shape_logs(self, prior: dict[str, float], lses: list[float], k: int) -> int:
        """Each hypothesis's log posterior (unnormalised) from the
        logsumexps of terms() at lses[k:]; returns the index past them."""
        self.per_shape: dict[str, float] = {}
        for name in prior:
            if name == UNKNOWN:
                continue
            if name in self.named:
                self.per_shape[name] = lses[k] + math.log(prior[name])
                k += 1
            else:
                self.per_shape[name] = -math.inf
        if UNKNOWN in prior:
            self.per_shape[UNKNOWN] = math.log(prior[UNKNOWN]) + lses[k]
            k += 1
        return k

    def result(self, total: float) -> Recognition:
        post = {k: math.exp(v - total) for k, v in self.per_shape.items()}
        top = max(post, key=post.__getitem__)
        if top == UNKNOWN:
            return Recognition(post, top, post[top], self.outline, None, (0, 0))
        _, pose, origin = self.best_of[top]      # the MAP placement of the most probable shape
        cells = pose.placed(*origin) if pose is not None else set()
        return Recognition(post, top, post[top], cells, pose, origin)


def _near_all(todo: Sequence[_Posterior], library: Library) -> None:
    """Every evidence's placements near its touches, the rows of one length
    (of every evidence) reduced in one call."""
    w_touch, w_cells, offset = _index_weights(library.key, todo[0].table.shape)
    groups: dict[tuple[int, int, int], list[tuple[_Posterior, np.ndarray, tuple]]] = {}
    for r in todo:
        # both counts of every origin and pose as the index of their entry in
        # the flat table (0/1 sums are exact integers in floats; two products,
        # not one of both: one twice the size is past OpenBLAS's threading
        # threshold, 30x slower on a loaded machine; in float32 when every
        # index is below 2^24, where its sums are as exact: half the product).
        # One evidence's at a time: a batch's in one product is slower, its
        # operands out of the cache
        win = r.win
        r.placements((win == OBJECT).astype(w_touch.dtype) @ w_touch
                     + (win == FREE).astype(w_touch.dtype) @ w_cells + offset)
        for key, ll, back in r.near_boxes():
            groups.setdefault(key, []).append((r, ll, back))
    for got in groups.values():
        ll = got[0][1] if len(got) == 1 else np.concatenate([g[1] for g in got])
        # each row's exp and sum as the pose's alone would be: the table is
        # finite, its max is read at the argmax the MAP needs anyway
        j = ll.argmax(axis=1)
        top = ll[_rows(len(ll)), j]
        sums = np.exp(ll - top[:, None]).sum(axis=1)
        jl, tl, sl = j.tolist(), top.tolist(), sums.tolist()
        lo = 0
        for r, part, back in got:
            hi = lo + len(part)
            r.reduced(back, jl[lo:hi], tl[lo:hi], sl[lo:hi])
            lo = hi


@functools.lru_cache(maxsize=256)
def _rows(n: int) -> np.ndarray:
    """0..n-1, to index each row once (read-only, shared: made per box it cost
    a tenth of a recognition)."""
    out = np.arange(n)
    out.flags.writeable = False
    return out


def _logsumexp_all(lists: Sequence[list[float]]) -> list[float]:
    """log(sum(exp(a))) of every list a (-inf for none), the lists of one
    length in one call: the max in Python, the exps and their sums in
    numpy, one row per list (each row's sum is that list's alone)."""
    out = [0.0] * len(lists)
    by_len: dict[int, list[int]] = {}
    for i, a in enumerate(lists):
        by_len.setdefault(len(a), []).append(i)
    for size, idx in by_len.items():
        ms = [max(lists[i]) if size else -math.inf for i in idx]
        live = [k for k, m in enumerate(ms) if m != -math.inf]
        for k, top in enumerate(ms):
            out[idx[k]] = top
        if not live:
            continue
        if len(live) == 1:         # one list (a run's recognition): no rows to stack
            k = live[0]
            sums = [float(np.exp(np.subtract(lists[idx[k]], ms[k])).sum())]
        else:
            rows = np.array([lists[idx[k]] for k in live], dtype=np.float64)
            tops = np.array([ms[k] for k in live], dtype=np.float64)
            sums = np.exp(np.subtract(rows, tops[:, None])).sum(axis=1).tolist()
        for k, s in zip(live, sums):
            out[idx[k]] = ms[k] + math.log(s)
    return out


@functools.lru_cache(maxsize=256)
def _table(key: tuple, n: int, eps_touch: float, eps_free: float, n_obj: int
           ) -> tuple[list[tuple[str, Pose]], list[int], list[float], list[float], np.ndarray,
                      list[tuple[tuple[int, int], np.ndarray, list[int], np.ndarray]]]:
    """The poses in order, their placements on the n x n arena, their
    placement priors, the log-likelihood of all of them away from the
    touches, and the log-likelihood table of a library (its key)
    with n_obj touches: the log-likelihood of a placement depends on it only
    through its pose and its two counts, so it is tabulated per pose (t
    touchable cells, its placement prior) and count, then looked up for
    every origin at once. Built once per process for each (a sweep's runs
    share the library and differ little in their touches; read-only)."""
    library = Library(dict(key))
    ordered = [(name, pose) for name in library.names for pose in library.poses[name]]
    fits = [(n - p.width + 1) * (n - p.height + 1) for _, p in ordered]
    place = [-math.log(len(library.poses[name])) - math.log(f) if f > 0 else 0.0
             for (name, _), f in zip(ordered, fits)]
    maxt = max(len(p.touchable) for _, p in ordered)
    lfact = np.array([math.lgamma(k + 1) for k in range(maxt + 1)])
    log_false = math.log(eps_touch / (n * n))
    log_true = math.log(1.0 - eps_touch)
    log_free = math.log(eps_free)
    t = np.array([len(p.touchable) for _, p in ordered])[:, None, None]
    k = np.arange(maxt + 1, dtype=np.int32)[None, :, None]
    f = np.arange(max(len(p.cells) for _, p in ordered) + 1, dtype=np.int32)[None, None, :]
    table = (k * log_true - (lfact[t] - lfact[np.maximum(t - k, 0)]) + (n_obj - k) * log_false
             + f * log_free + np.array(place)[:, None, None])
    table.flags.writeable = False
    by_box: dict[tuple[int, int], list[int]] = {}
    for column, (_, p) in enumerate(ordered):
        if fits[column] > 0:
            by_box.setdefault((p.width, p.height), []).append(column)
    # each box's columns as an index array and a list, and its rows: a
    # recognition reads them per box (numpy calls on small arrays cost most
    # of it)
    boxes = [(box, np.array(cols), cols, np.arange(len(cols))) for box, cols in by_box.items()]
    # every placement away from the touches, when none is near them
    far = [pl + math.log(f) + n_obj * log_false if f > 0 else 0.0 for pl, f in zip(place, fits)]
    return ordered, fits, place, far, table, boxes


@functools.lru_cache(maxsize=32)
def _index_weights(key: tuple, shape: tuple[int, ...]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """What turns a window's OBJECT and FREE indicators into the flat index
    into the (poses, touch counts, free counts) table of `shape` for every
    pose: a touchable cell weighs a touch count's stride, any cell of the
    pose one, and the pose's own rows are an offset. Built once per process
    per library (read-only, shared). float32 while every flat index is an
    integer float32 holds exactly (below 2^24), float64 beyond."""
    _, _, m_touch, m_cells = _masks(key)
    dtype = np.float32 if math.prod(shape) < 2 ** 24 else np.float64
    out = ((m_touch * shape[2]).astype(dtype), m_cells.astype(dtype),
           np.arange(shape[0], dtype=dtype) * (shape[1] * shape[2]))
    for a in out:
        a.flags.writeable = False
    return out


def _free_form(cells: set[Cell], n: int, n_obj: int, log_true: float) -> float:
    """log P(this free-form shape, placed here | UNKNOWN) + log P(the touches
    | it): the polyomino prior, a uniform placement on the n x n grid, and
    the n_obj touches drawn from its touchable cells (no free cell is in it)."""
    wide = max(c[0] for c in cells) - min(c[0] for c in cells) + 1
    high = max(c[1] for c in cells) - min(c[1] for c in cells) + 1
    t = max(touchable(cells), n_obj)
    return (log_polyomino_prior(len(cells)) - math.log(max(1, (n - wide + 1) * (n - high + 1)))
            + n_obj * log_true - (math.lgamma(t + 1) - math.lgamma(t - n_obj + 1)))


def estimate(ev: Evidence, rec: Recognition, threshold: float = THRESHOLD) -> set[Cell]:
    """The best shape estimate: the MAP placement of a recognised library
    shape, otherwise (undecided, or UNKNOWN) the evidence's own outline, the
    touched cells' hull minus every known-free cell."""
    if rec.recognised(threshold) and rec.map_pose is not None:
        return set(rec.map_cells)
    return ev.hull_estimate()
