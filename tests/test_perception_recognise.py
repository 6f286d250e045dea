"""Recognition (perception/recognise.py): every library shape, in
every orientation and several placements, is recognised from its full
evidence; the posterior sharpens as touches arrive."""

from __future__ import annotations

import numpy as np
import pytest

from perception.evidence import Evidence
from perception.recognise import P_OPEN, THRESHOLD, UNKNOWN, estimate, priors, recognise
from perception.shapes import TRANSFORMS, Library, normalise, orientations
from sim_backend import objects

LIB = Library.builtin()
STEPS8 = [(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1) if (dx, dy) != (0, 0)]


def full_evidence(cells: set[tuple[int, int]], world: int = 18) -> Evidence:
    """Every touchable cell touched, every cell around the shape seen free."""
    ev = Evidence(world)
    for x, y in sorted(cells):
        if any((x + dx, y + dy) not in cells for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1))):
            ev.touch(x, y)
    for x, y in cells:
        for dx, dy in STEPS8:
            if (x + dx, y + dy) not in cells:
                ev.free(x + dx, y + dy)
    return ev


def test_distinct_orientations_of_symmetric_shapes():
    counts = {name: len(LIB.poses[name]) for name in LIB.names}
    assert counts["plus"] == 1 and counts["square"] == 1
    assert counts["bar"] == 2 and counts["T"] == 4
    assert all(1 <= c <= 8 for c in counts.values())
    # every image of a shape under the 8 maps is one of its poses
    for name in LIB.names:
        poses = {p.cells for p in LIB.poses[name]}
        for t in TRANSFORMS:
            assert normalise(t(x, y) for x, y in objects.offsets(name)) in poses


@pytest.mark.parametrize("name", list(objects.SHAPES))
@pytest.mark.parametrize("k", range(8))
def test_each_shape_in_each_orientation_and_placement_is_recognised(name, k):
    image = normalise(TRANSFORMS[k](x, y) for x, y in objects.offsets(name))
    for ox, oy in ((-16, -16), (0, 0), (5, -9), (16 - max(c[0] for c in image),
                                                  16 - max(c[1] for c in image))):
        placed = {(ox + x, oy + y) for x, y in image}
        rec = recognise(full_evidence(placed), LIB)
        assert rec.best == name, (name, k, ox, oy, rec.posterior)
        assert rec.recognised(THRESHOLD), rec.posterior
        assert rec.map_cells == placed
        assert abs(sum(rec.posterior.values()) - 1.0) < 1e-9


def test_no_touch_gives_the_uniform_prior_and_the_empty_estimate():
    ev = Evidence(18)
    ev.free(0, 0)
    rec = recognise(ev, LIB)
    assert rec.best is None and not rec.recognised()
    assert rec.posterior == priors(LIB, P_OPEN)
    assert rec.posterior[UNKNOWN] == P_OPEN
    assert set(rec.posterior.values()) - {P_OPEN} == {(1 - P_OPEN) / len(LIB.names)}
    assert estimate(ev, rec) == set()


def test_posterior_sharpens_as_touches_arrive():
    """The cross (thesis '+'), touched from one arm outwards, with the robots'
    cells beside the touched ones seen free as they would be."""
    cells = set(objects.cells("cross", 0, 0))
    order = [(3, 0), (4, 0), (6, 1), (6, -2), (1, 0), (8, 0), (6, 4), (6, -1), (6, 5)]
    assert set(order) <= cells
    ev = Evidence(18)
    ps, closed = [], []
    for x, y in order:
        ev.touch(x, y)
        for dx, dy in ((0, 1), (0, -1), (1, 0), (-1, 0)):
            if (x + dx, y + dy) not in cells:
                ev.free(x + dx, y + dy)
        ps.append(recognise(ev, LIB).posterior["cross"])
        closed.append(recognise(ev, LIB, p_open=0.0).posterior["cross"])
    assert ps[0] < 0.5 and closed[0] < 0.5   # one touch says little
    assert ps[-1] >= THRESHOLD and closed[-1] >= THRESHOLD
    # over the library alone: monotone-ish, never falls by more than a little
    assert all(b >= a - 0.05 for a, b in zip(closed, closed[1:])), closed
    # with the open set: three scattered touches may fit a free-form shape
    # better for a while, but once the cross leads it keeps its lead
    lead = next(j for j, p in enumerate(ps) if p >= 0.5)
    assert all(b >= a - 0.05 for a, b in zip(ps[lead:], ps[lead + 1:])), ps
    rec = recognise(ev, LIB)
    assert estimate(ev, rec) == cells        # recognised: the MAP placement


def test_unrecognised_evidence_falls_back_to_the_hull_minus_free():
    # two identical candidates: neither can pass the threshold
    twins = Library({"a": objects.offsets("bar"), "b": objects.offsets("bar")})
    ev = Evidence(18)
    for c in [(0, 0), (3, 0), (0, 3)]:
        ev.touch(*c)
    ev.free(1, 1)
    rec = recognise(ev, twins, p_open=0.0)      # a closed library of the twins
    assert abs(rec.p - 0.5) < 1e-9 and not rec.recognised()
    triangle = {(x, y) for x in range(4) for y in range(4) if x + y <= 3}
    assert estimate(ev, rec) == triangle - {(1, 1)}


def test_a_known_shape_joins_the_library():
    zig = [(0, 0), (1, 0), (1, 1), (2, 1), (2, 2), (3, 2)]
    lib = Library.builtin({"zigzag": zig})
    assert "zigzag" in lib.names and len(lib.names) == len(objects.SHAPES) + 1
    placed = {(x + 2, y - 3) for x, y in orientations(zig)[3]}
    rec = recognise(full_evidence(placed), lib)
    assert rec.best == "zigzag" and rec.map_cells == placed


def test_bad_rates_and_empty_library_are_refused():
    with pytest.raises(ValueError, match="eps_touch"):
        recognise(Evidence(5), LIB, eps_touch=0.0)
    with pytest.raises(ValueError, match="at least one"):
        Library({})


def test_the_index_products_are_float32_only_while_every_index_is_exact_in_it() -> None:
    # the products' sums are whole table indices: float32 holds them exactly
    # below 2^24 entries only, so a larger table needs float64
    from perception.recognise import _index_weights
    key = Library.builtin().key
    small = _index_weights(key, (28, 10, 10))
    large = _index_weights(key, (28, 1 << 10, 1 << 10))
    assert all(a.dtype == np.float32 for a in small)
    assert all(a.dtype == np.float64 for a in large)
    assert large[2][-1] == 27 * (1 << 20) and large[0].max() == 1 << 10
