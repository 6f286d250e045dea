"""The pieces a run's summary shares or shortcuts: the outline computed once
per set of cells, and joined touches that are already one piece."""

from firmware_logic import perception
from perception.evidence import Evidence, connected, outline


def test_connected_is_one_4_connected_piece() -> None:
    assert connected([(0, 0), (1, 0), (1, 1), (1, 2)])
    assert not connected([(0, 0), (1, 1)])            # diagonal neighbours only
    assert not connected([(0, 0), (1, 0), (3, 0)])
    assert connected([])


def test_outline_is_outline_cells_and_a_new_set_each_time() -> None:
    cells = [(0, 0), (4, 0), (0, 3), (4, 3)]
    first = outline(cells)
    assert first == perception.outline_cells(cells)
    first.clear()                                      # a caller's own set
    assert outline(reversed(cells)) == perception.outline_cells(cells)


def test_joined_touches_in_one_piece_are_the_touches() -> None:
    ev = Evidence(10)
    for c in [(0, 0), (1, 0), (2, 0), (2, 1)]:
        ev.touch(*c)
    ev.free(1, 1)
    assert ev.joined() == {(0, 0), (1, 0), (2, 0), (2, 1)}


def test_joined_touches_apart_are_joined_around_free_cells() -> None:
    ev = Evidence(10)
    for c in [(0, 0), (2, 0)]:
        ev.touch(*c)
    ev.free(1, 0)
    shape = ev.joined()
    assert {(0, 0), (2, 0)} <= shape and (1, 0) not in shape
    assert connected(shape) and len(shape) == 5       # around the free cell: 3 more
