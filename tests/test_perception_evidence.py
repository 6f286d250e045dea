"""The evidence grid (perception/evidence.py): touches mark object,
poses mark free, a cell is never both."""

from __future__ import annotations

import pytest

from perception.evidence import FREE, OBJECT, UNKNOWN, Evidence, iou
from firmware_logic import perception


def test_a_touch_marks_object_and_a_pose_marks_free():
    ev = Evidence(10)
    assert ev.at(2, 3) == UNKNOWN
    assert ev.touch(2, 3) is True
    assert ev.free(4, 4) is True
    assert ev.at(2, 3) == OBJECT and ev.at(4, 4) == FREE
    assert ev.touched == [(2, 3)] and ev.free_set() == {(4, 4)}
    # the same news twice is no news
    assert ev.touch(2, 3) is False and ev.free(4, 4) is False
    assert ev.free_cells == 1 and ev.conflicts == 0


def test_a_free_observation_of_a_touched_cell_is_ignored_and_counted():
    ev = Evidence(10)
    ev.touch(1, 1)
    v = ev.version
    assert ev.free(1, 1) is False
    assert ev.at(1, 1) == OBJECT and ev.conflicts == 1 and ev.version == v
    assert ev.free_cells == 0


def test_a_touch_on_a_cell_seen_free_makes_it_object():
    ev = Evidence(10)
    ev.free(0, 0)
    assert ev.touch(0, 0) is True
    assert ev.at(0, 0) == OBJECT and ev.conflicts == 1 and ev.free_cells == 0
    assert (0, 0) not in ev.free_set()


def test_cells_off_the_arena_are_not_evidence():
    ev = Evidence(5)
    assert ev.touch(6, 0) is False and ev.free(0, -6) is False
    assert ev.version == 0 and ev.at(6, 0) == UNKNOWN


def test_bad_arena_size_is_refused():
    with pytest.raises(ValueError, match="world_size"):
        Evidence(0)


def test_heartbeat_pose_is_rounded_and_shifted_into_the_objects_frame():
    ev = Evidence(10)
    # Q8 pose (3.5, -2.4) rounds to patch (4, -2); the object moved by (1, -1)
    assert ev.heartbeat((0, 3 * 256 + 128, -2 * 256 - 102, 90, 0), moved=(1, -1)) is True
    assert ev.free_set() == {(3, -1)}


def test_hull_estimate_drops_known_free_cells_and_uncertainty_adds_up():
    ev = Evidence(10)
    for c in [(0, 0), (4, 0), (0, 4), (4, 4)]:
        ev.touch(*c)
    hull = ev.hull_cells()
    assert hull == perception.outline_cells(ev.touched) and len(hull) == 25
    ev.free(2, 2)
    ev.free(1, 3)
    ev.free(9, 9)                          # outside the hull: no effect on it
    est = ev.hull_estimate()
    assert est == hull - {(2, 2), (1, 3)}
    u = ev.uncertainty()
    assert u == {"object": 4, "free": 2, "unknown": 19}
    assert sum(u.values()) == len(hull)


def test_iou():
    assert iou({(0, 0), (1, 0)}, {(1, 0), (2, 0)}) == round(1 / 3, 6)
    assert iou(set(), set()) == 0.0
