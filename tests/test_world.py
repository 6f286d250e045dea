"""The simulated world: objects, Signal, placement and the tick conflict rules."""

import pytest

from firmware_logic import fixedpoint as fx
from firmware_logic.behaviours.thesis import robot as R
from sim_backend import objects
from sim_backend.engine import Engine
from sim_backend.scenario import Scenario, validate
from sim_backend.world import BLUE, World, signal_table


def test_draw_object_shapes_match_the_thesis():
    bar = set(objects.offsets("bar"))
    assert bar == {(a, y) for a in range(1, 9) for y in (0, 1)}
    assert set(objects.offsets("L")) == {(a, 0) for a in range(1, 9)} | {(1, a) for a in range(1, 9)}
    cross = set(objects.offsets("cross"))
    assert (0, 0) in cross and (6, -2) in cross and (6, 5) in cross and len(cross) == 16   # arms share (6, 0)
    x = set(objects.offsets("X"))
    assert (8, 8) in x and (8, 0) in x and (1, 7) in x and (0, 8) not in x


def test_signal_is_round_10_over_1_plus_d_within_radius():
    t = {(dx, dy): v for dx, dy, v in signal_table(5)}
    assert t[(0, 0)] == 10
    assert t[(1, 0)] == 5
    assert t[(3, 0)] == 3            # 2.5 rounds half up, as NetLogo does
    assert t[(3, 4)] == 2            # d = 5, on the radius: 10/6 -> 2
    assert (4, 4) not in t           # d = 5.66 > sigRadius


def test_field_adds_up_and_is_removed_with_the_beacon():
    w = World(Scenario(), 1)
    w.signal(0, 0)
    w.signal(1, 0)
    assert w.field[w.idx(0, 0)] == 15
    w.signal(0, 0, sign=-1)
    assert w.field[w.idx(0, 0)] == 5


def test_placement_is_seeded_and_off_the_object():
    a, b, c = World(Scenario(), 5), World(Scenario(), 5), World(Scenario(), 6)
    assert (a.xs, a.ys, a.object_cells) == (b.xs, b.ys, b.object_cells)
    assert (a.xs, a.ys) != (c.xs, c.ys)
    cells = set(a.object_cells)
    starts = {(fx.patch(x), fx.patch(y)) for x, y in zip(a.xs, a.ys)}
    assert len(starts) == 20 and not starts & cells
    assert 0 <= a.obj_x <= 9 and 0 <= a.obj_y <= 9


@pytest.mark.parametrize("starts", ["redraw", "netlogo"])
def test_start_occupancy_is_the_kernels_recount(starts):
    # World counts its robots' patches itself at its start; kernel.recount
    # (what every tick does) must find the same grid
    for seed in range(1, 9):
        w = World(validate({"agents": 300, "worldSize": 18, "starts": starts}), seed)
        counted = list(w.occ)
        assert sum(counted) == 300
        if starts == "netlogo":
            assert max(counted) > 1          # robots may share a patch there
        w.occ[:] = [7] * len(w.occ)
        w.recount()
        assert w.occ == counted


def _two_robot_engine():
    sc = validate({"agents": 2, "objectWeight": 1.0, "objectX": 5, "objectY": 5})
    e = Engine(sc, 1)
    return e


def test_two_robots_entering_one_patch_lower_node_wins():
    e = _two_robot_engine()
    w = e.world
    w.xs[:] = [0, 2 * 256]
    w.ys[:] = [0, 0]
    w.recount()
    for b in e.bodies:
        b.reset_intents()
    e.bodies[0].forward(90, 256)       # both into patch (1, 0)
    e.bodies[1].forward(270, 256)
    e._apply()
    assert (w.xs, w.ys) == ([256, 512], [0, 0])


def test_cannot_enter_a_patch_occupied_at_tick_start_or_the_object():
    e = _two_robot_engine()
    w = e.world
    w.xs[:] = [0, 256]
    w.ys[:] = [0, 0]
    w.recount()
    for b in e.bodies:
        b.reset_intents()
    e.bodies[0].forward(90, 256)       # into robot 2's patch, which leaves it
    e.bodies[1].forward(90, 256)
    e._apply()
    assert w.xs == [0, 512]
    ox, oy = w.object_cells[0]
    w.xs[:] = [(ox - 1) * 256, -5 * 256]
    w.ys[:] = [oy * 256, 0]
    w.recount()
    for b in e.bodies:
        b.reset_intents()
    e.bodies[0].forward(90, 256)
    e._apply()
    assert w.xs[0] == (ox - 1) * 256


def test_claim_race_lowest_node_wins_and_loser_resumes():
    e = _two_robot_engine()
    w = e.world
    ox, oy = w.object_cells[0]             # bar cell (6, 5)
    w.xs[:] = [(ox - 1) * 256, ox * 256]
    w.ys[:] = [oy * 256, (oy - 1) * 256]
    w.recount()
    for b in e.bodies:
        b.reset_intents()
    e.bodies[0].claim(90)
    e.bodies[1].claim(0)
    e._apply()
    k = w.idx(ox, oy)
    assert w.obj[k] == BLUE and w.owner[k] == 1
    assert e.bodies[0].holding() == 1 and e.bodies[1].holding() == 0


def test_probe_sees_the_world_as_at_tick_start():
    e = _two_robot_engine()
    w = e.world
    w.xs[:] = [0, 256]
    w.ys[:] = [0, 0]
    w.recount()
    assert e.bodies[0].probe(90) == R.ROBOT
    assert e.bodies[1].probe(270) == R.ROBOT
    ox, oy = w.object_cells[0]
    w.xs[0], w.ys[0] = (ox - 1) * 256, oy * 256
    w.recount()
    assert e.bodies[0].probe(90) == R.OBJECT
    w.obj[w.idx(ox, oy)] = BLUE
    assert e.bodies[0].probe(90) == R.CLAIMED
    w.xs[0] = 18 * 256
    assert e.bodies[0].probe(90) == R.WALL


def test_uphill_points_to_strongest_neighbour():
    e = _two_robot_engine()
    w = e.world
    w.xs[0], w.ys[0] = 0, 0
    w.signal(-3, -3)
    assert e.bodies[0].uphill() == 225
    w.signal(0, 0)
    w.signal(0, 0)
    assert e.bodies[0].uphill() == -1          # already on the peak
