"""The thesis's own shape measure: the polygon through the holders'
rounded positions (DrawShape's shape.txt, Figures 22-24) and the IoU with
the object of the cells it encloses, `polygon_iou`, beside `shape_iou` in
summary.json, sweep.csv, the trace and the touchmap figures."""

from __future__ import annotations

import csv
from pathlib import Path

from perception.polygon import enclosed_cells, polygon, polygon_iou, strictly_inside
from sim_backend import engine, objects, plots, scenario, sweep, trace

BAR = objects.cells("bar", 0, 0)          # x 1..8, y 0..1


def _ring(cells: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """Every patch next to the cells (8-neighbours), not on them."""
    cs = set(cells)
    return sorted({(x + dx, y + dy) for x, y in cs for dx in (-1, 0, 1) for dy in (-1, 0, 1)}
                  - cs)


def test_holders_all_round_a_bar_enclose_exactly_the_bar() -> None:
    assert enclosed_cells(_ring(BAR)) == set(BAR)
    assert polygon_iou(_ring(BAR), BAR) == 1.0


def test_four_corner_holders_give_a_quadrilateral_that_covers_the_bar() -> None:
    corners = [(0, -1), (9, -1), (9, 2), (0, 2)]
    poly = polygon(corners)
    assert len(poly) == 5 and poly[0] == poly[-1] and set(poly) == set(corners)
    assert enclosed_cells(corners) == set(BAR)


def test_holders_on_one_side_enclose_little_and_the_iou_falls() -> None:
    # a triangle from three holders below the bar and one above its left end
    holders = [(0, -1), (4, -1), (9, -1), (1, 2)]
    inside = enclosed_cells(holders)
    assert inside and inside < set(BAR)
    assert 0 < polygon_iou(holders, BAR) < 1
    assert polygon_iou(holders, BAR) == round(len(inside) / len(BAR), 6)


def test_fewer_than_three_holders_or_a_line_enclose_nothing() -> None:
    for holders in ([], [(0, -1)], [(0, -1), (9, -1)], [(0, -1), (4, -1), (9, -1)]):
        assert enclosed_cells(holders) == set(), holders
        assert polygon_iou(holders, BAR) == 0.0
    assert polygon_iou([], []) == 0.0


def test_a_cell_on_the_boundary_is_not_inside() -> None:
    square = polygon([(0, 0), (2, 0), (2, 2), (0, 2)])
    assert strictly_inside(square, (1, 1))
    for p in ((0, 0), (1, 0), (2, 1), (1, 2), (0, 1), (3, 1), (-1, 1)):
        assert not strictly_inside(square, p), p
    # a concave (star) polygon, its notch at (2, 1) below the centroid: the
    # cells in the notch are outside
    arrow = polygon([(0, 0), (4, 0), (4, 4), (2, 1), (0, 4)])
    assert arrow == [(0, 0), (2, 1), (4, 0), (4, 4), (0, 4), (0, 0)]
    assert strictly_inside(arrow, (2, 2)) and strictly_inside(arrow, (1, 1))
    assert not strictly_inside(arrow, (2, 0)) and not strictly_inside(arrow, (1, 0))


def _thesis_run(**keys) -> engine.RunResult:
    sc = scenario.validate({"agents": 20, "maxTicks": 400, **keys})
    return engine.Engine(sc, seed=3).run()


def test_the_summary_and_the_trace_carry_it_from_the_holders_positions() -> None:
    sc = scenario.validate({"agents": 20, "maxTicks": 400})
    e = engine.Engine(sc, seed=3)
    t = trace.Trace(e)
    r = e.run()
    s = r.summary()
    assert s["touches"], "the run should have holders"
    want = polygon_iou([tuple(p) for p in s["touches"]], r.world.start_cells)
    assert s["polygon_iou"] == want and 0 < want <= 1
    assert s["polygon_iou"] != s["shape_iou"]
    last = dict(zip(t.names, t.rows[-1]))
    assert last["polygon_iou"] == s["polygon_iou"] and last["shape_iou"] == s["shape_iou"]
    first = dict(zip(t.names, t.rows[0]))
    assert first["polygon_iou"] == 0.0


def test_a_sweep_row_has_it_and_it_can_be_recomputed_from_the_row(tmp_path: Path) -> None:
    sc = scenario.validate({"agents": 20, "maxTicks": 400, "object": "L"})
    pt = sweep.Point("p", (("object", "L"),))
    s = engine.Engine(sc, seed=5).run().summary()
    row = sweep.make_row(pt, sc, 5, s, "delivered")
    path = sweep.write_csv([row], tmp_path / "sweep.csv", sweep.columns(["thesis"]))
    got = next(csv.DictReader(path.open()))
    true = plots._true_cells(got)
    assert float(got["polygon_iou"]) == polygon_iou(plots._pairs(got["touches"]), true)
    assert float(got["polygon_iou"]) == s["polygon_iou"]


def test_the_touchmap_figure_draws_the_declared_column(tmp_path: Path) -> None:
    rows = []
    for seed in (1, 2):
        for w in (4.0, 6.0):
            sc = scenario.validate({"agents": 20, "maxTicks": 600, "objectWeight": w})
            pt = sweep.Point("shapes", (("objectWeight", w),))
            rows.append(sweep.make_row(pt, sc, seed, engine.Engine(sc, seed=seed).run().summary(),
                                       "converged"))
    path = sweep.write_csv(rows, tmp_path / "sweep.csv", sweep.columns(["thesis"]))
    read = sweep.read_csv(path)
    fig = {"name": "t", "kind": "touchmap", "experiment": "shapes", "levels": ("bar",),
           "y": "polygon_iou"}
    table = plots.shape_table(read, fig)
    assert [p[0] for p in table["bar"]] == [4, 6]
    assert table["bar"] != plots.shape_table(read, fig, "shape_iou")["bar"]
    assert plots.touchmap_plot(read, fig, tmp_path / "t.png").stat().st_size > 1000


def test_the_row_scan_encloses_what_the_point_test_says() -> None:
    import random
    rnd = random.Random(7)
    for _ in range(300):
        w = rnd.choice((3, 6, 12))
        pts = [(rnd.randint(-w, w), rnd.randint(-w, w)) for _ in range(rnd.randint(0, 12))]
        poly = polygon(pts)
        want = set()
        if len(poly) >= 4:
            want = {(x, y) for x in range(-w, w + 1) for y in range(-w, w + 1)
                    if strictly_inside(poly, (x, y))}
        assert enclosed_cells(pts) == want, pts
