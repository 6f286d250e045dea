from firmware_logic import perception as P


def test_convex_hull_of_a_rectangle_and_its_raster():
    pts = [(0, 0), (3, 0), (3, 1), (0, 1), (1, 0), (2, 1)]
    assert set(P.convex_hull(pts)) == {(0, 0), (3, 0), (3, 1), (0, 1)}
    assert P.outline_cells(pts) == {(x, y) for x in range(4) for y in range(2)}


def test_degenerate_outlines_are_the_segments():
    assert P.outline_cells([(1, 1)]) == {(1, 1)}
    assert P.outline_cells([(1, 1), (4, 1)]) == {(1, 1), (4, 1)}


def test_iou_counts():
    assert P.iou_counts({(0, 0), (1, 0)}, {(1, 0), (2, 0)}) == (1, 3)
