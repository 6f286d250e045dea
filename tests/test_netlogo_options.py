"""Each departure from Appendix A's NetLogo code is a named scenario option
(sim_backend/scenario.py CHOICES); with "netlogo" the rule is the thesis's.
One test per rule, on small worlds with fixed seeds; the differential
harness (reference == batch bit for bit) covers the options together."""

import math
import random

import pytest

from firmware_logic import fixedpoint as fx
from firmware_logic.behaviours.thesis import robot as R
from firmware_logic.behaviours.thesis.robot import Robot
from firmware_logic.rng import Rng
from sim_backend import registry
from sim_backend import kernel
from sim_backend.engine import Engine
from sim_backend.scenario import CHOICES, Scenario, validate
from sim_backend.world import World
from tests.fakehal import FakeHal
from tests.harness import assert_same
from tests.test_coordinator import drive_home, hello, touch

SMALL = {"agents": 4, "objectWeight": 2, "worldSize": 10, "objectX": -4, "objectY": 6, "homeX": -7, "homeY": -7}


def world(**over):
    return World(validate({**SMALL, **over}), 5)


def put(w, px, py, v):
    w.field[w.idx(px, py)] = v


# -- uphill ------------------------------------------------------------------------

def test_uphill_ties_are_drawn_at_random_among_the_highest_neighbours():
    w = world(uphillTies="netlogo")
    w.xs[0], w.ys[0] = 0, 0
    put(w, 0, 0, 3)
    for px, py in ((0, 1), (1, 0), (-1, -1)):      # N, E, SW tie at 7
        put(w, px, py, 7)
    put(w, 1, 1, 6)
    got = [w.uphill(0) for _ in range(300)]
    assert set(got) == {0, 90, 225}
    assert min(got.count(h) for h in (0, 90, 225)) > 60      # about a third each
    w.run.ties[0] = kernel.ORDERED
    assert {w.uphill(0) for _ in range(20)} == {0}          # the default: first in order


def test_uphill_moves_only_to_a_strictly_higher_patch():
    w = world(uphillTies="netlogo")
    w.xs[0], w.ys[0] = 0, 0
    put(w, 0, 0, 7)
    put(w, 0, 1, 7)
    put(w, 1, 0, 7)
    assert [w.uphill(0) for _ in range(20)] == [-1] * 20
    assert w.tie[0] == kernel.tie_seed(5, 1)                # no draw when staying


def test_uphill_tie_draws_repeat_for_the_same_seed():
    a, b = world(uphillTies="netlogo"), world(uphillTies="netlogo")
    for w in (a, b):
        w.xs[0], w.ys[0] = 0, 0
        put(w, 0, 1, 5)
        put(w, 0, -1, 5)
    assert [a.uphill(0) for _ in range(50)] == [b.uphill(0) for _ in range(50)]


def test_netlogo_uphill_heading_points_at_the_winning_patch_centre_from_the_robot():
    for heading in ("octant", "netlogo"):
        w = world(uphillHeading=heading)
        w.xs[0], w.ys[0] = 100, -100                     # SE of its patch centre
        put(w, 1, 1, 7)                                 # NE neighbour wins
        got = w.uphill(0)
        if heading == "octant":
            assert got == 45
        else:
            # towards (1, 1) from (0.39, -0.39): atan2(0.61, 1.39) = 23.7 degrees
            assert got == round(math.degrees(math.atan2(256 - 100, 256 + 100)))
    w = world(uphillHeading="netlogo")
    w.xs[0], w.ys[0] = 0, 0                             # at the centre: the octant itself
    put(w, -1, 0, 4)
    assert w.uphill(0) == 270


# -- HeadCarefully's probe -----------------------------------------------------------

def probe_self(rule):
    w = world(probeSelf=rule)
    w.xs[0], w.ys[0] = 120, 120                         # NE corner of patch (0, 0)
    for i in (1, 2, 3):                                 # the others well away
        w.xs[i], w.ys[i] = 5 * 256, 2 * i * 256
    w.recount()
    # heading 225: the point one ahead (-61, -61) in Q8 is still patch (0, 0)
    return kernel.probe(w.grid, w.run, 0, w.xs[0], w.ys[0], 225), \
        kernel.probe(w.grid, w.run, 0, w.xs[0], w.ys[0], 45)


def test_netlogo_probe_counts_the_robot_itself_in_its_own_patch():
    assert probe_self("skip") == (kernel.NOTHING, kernel.NOTHING)
    assert probe_self("netlogo") == (kernel.ROBOT, kernel.NOTHING)   # 45: the next patch


# -- the first go iteration ----------------------------------------------------------

def test_netlogo_first_move_moves_before_the_first_look():
    def ticks(rule):
        robot = registry.load("thesis").make_robot(1, 3, validate({"firstMove": rule}))
        out = []
        for _ in range(2):
            hal = FakeHal()
            robot.step(hal)
            out.append([c[0] for c in hal.log if c[0] in ("probe", "field_ahead", "forward")])
        return out
    look, move = ticks("look"), ticks("netlogo")
    # the default: FindObject (four probes), FindField, RandomHead on tick 1
    assert look[0] == ["probe"] * 4 + ["field_ahead", "probe", "forward"]
    # go's order: RandomHead alone on tick 1 (HeadCarefully's probe, fd 1),
    # then FindObject, FindField, RandomHead as the default's rotation
    assert move[0] == ["probe", "forward"]
    assert move[1] == look[1] == ["probe"] * 4 + ["field_ahead", "probe", "forward"]


# -- Signal ------------------------------------------------------------------------

def beacon_on(w, i, x, y, value=1):
    w.xs[i], w.ys[i] = x, y
    w.beacon_set[i] = value


def apply(w, tick):
    w.apply(tick)
    for i in range(len(w.xs)):
        w.beacon_set[i] = -1


def test_netlogo_signal_is_centred_on_the_finders_position():
    w = world(signalMode="netlogo", sigRadius=3)
    x = 102                                             # 0.4 patch east of (0, 0)
    beacon_on(w, 0, x, 0)
    apply(w, 1)
    for px in range(-3, 4):
        d = abs(px - x / 256)
        assert w.field[w.idx(px, 0)] == math.floor(10 / (1 + d) + 0.5), px
    assert w.field[w.idx(0, 0)] == 7 and w.field[w.idx(1, 0)] == 6
    assert w.field[w.idx(0, 4)] == 0                    # in-radius by patch centres
    p = world(sigRadius=3)
    beacon_on(p, 0, x, 0)
    apply(p, 1)
    assert p.field[p.idx(0, 0)] == 10 and p.field[p.idx(1, 0)] == 5


def test_netlogo_signal_is_once_per_tick_for_the_last_finder():
    w = world(signalMode="netlogo", sigRadius=2)
    beacon_on(w, 0, -5 * 256, 0)
    beacon_on(w, 2, 5 * 256, 0)
    apply(w, 1)
    assert w.field[w.idx(-5, 0)] == 0                  # node 1 found too, but no Signal
    assert w.field[w.idx(5, 0)] == 10                  # node 3 was the last setter of found
    w.beacon_set[0] = 0                                 # its beacon off removes nothing
    w.beacon_set[2] = 0
    apply(w, 2)
    assert sum(w.field) == 0
    p = world(sigRadius=2)
    beacon_on(p, 0, -5 * 256, 0)
    beacon_on(p, 2, 5 * 256, 0)
    apply(p, 1)
    assert p.field[p.idx(-5, 0)] == 10 and p.field[p.idx(5, 0)] == 10


# -- set field 10 ------------------------------------------------------------------

def test_a_leaders_patch_is_reset_to_10_every_tick():
    w = world(sigRadius=4)
    beacon_on(w, 0, 0, 0, value=2)                     # a leader
    beacon_on(w, 1, 2 * 256, 0)                        # a holder next to it
    apply(w, 1)
    # pinned to 10, then both Signals add (go's ask, then Signal): its own 10, the
    # neighbour's round(10 / 3) = 3
    assert w.field[w.idx(0, 0)] == 10 + 10 + 3
    for t in range(2, 6):
        put(w, 0, 0, 99)
        apply(w, t)
        assert w.field[w.idx(0, 0)] == 10
    w.beacon_set[1] = 0
    apply(w, 6)
    assert w.field[w.idx(0, 0)] == 10


def touch_from(state, leader_field):
    r, hal = Robot(3, 7, R.FIREFLY, 45, 2, 100, leader_field), FakeHal()
    r.state = state                                     # FIELD: phase 0, FindObject first
    hal.probes = {90: R.OBJECT}
    r.step(hal)
    r.step(hal)
    return [c for c in hal.log if c[0] == "beacon"]


def test_a_robot_that_touched_from_search_lights_a_leaders_beacon():
    assert touch_from(R.SEARCH, 1) == [("beacon", 2)]
    assert touch_from(R.FIELD, 1) == [("beacon", 1)]    # foundField: no leader
    assert touch_from(R.SEARCH, 0) == [("beacon", 1)]   # the option off


# -- arrival ------------------------------------------------------------------------

def carry_home(arrival):
    sc = validate({"arrival": arrival, "objectWeight": 1})
    c = registry.load("thesis").coordinator(sc)
    hello(c, 1)
    touch(c, 1, 1, (-9, -9), 5, robot=(-10, -9))
    c.tick(5)
    pose = drive_home(c, [-10, -9])
    assert c.delivered_tick > 0
    return pose


def test_netlogo_arrival_is_a_holder_within_1_of_home():
    x, y = carry_home("netlogo")
    assert (x + 15) ** 2 + (y + 15) ** 2 < 1
    x, y = carry_home("within4")
    assert 1 <= (x + 15) ** 2 + (y + 15) ** 2 < 16


def test_a_netlogo_run_ends_with_a_holder_on_home():
    sc = validate({"arrival": "netlogo"})
    res = Engine(sc, 4).run()
    assert res.delivered
    w = res.world
    on_home = [i for i in range(sc.agents)
               if w.held[i] >= 0 and (fx.patch(w.xs[i]), fx.patch(w.ys[i])) == (-15, -15)]
    assert on_home


# -- start positions ----------------------------------------------------------------

def test_netlogo_starts_walk_fd_random_max_pxcor_along_the_robots_own_heading():
    sc = validate({"starts": "netlogo", "agents": 60})
    shared = 0
    for seed in range(5):
        w = World(sc, seed)
        setup = Rng(seed, 0)
        setup.below(10), setup.below(10)                 # CreateWorld's objx, objy
        cells = set()
        for i in range(sc.agents):
            robot = registry.load("thesis").make_robot(i + 1, seed, sc)
            dist = setup.below(sc.worldSize) * fx.ONE
            assert (w.xs[i], w.ys[i]) == (fx.dx(robot.heading, dist), fx.dy(robot.heading, dist))
            p = (fx.patch(w.xs[i]), fx.patch(w.ys[i]))
            shared += p in cells
            cells.add(p)
    assert shared > 0                                   # NetLogo turtles may share a patch


# -- engines --------------------------------------------------------------------------

def test_the_netlogo_scenario_sets_every_option_to_the_thesis_rule():
    from sim_backend import scenario
    sc = scenario.load("netlogo")
    assert all(getattr(Scenario(), k) != "netlogo" for k in CHOICES)    # not the defaults
    assert all(getattr(sc, k) == "netlogo" for k in CHOICES)


def test_options_are_named_and_bad_values_refused():
    sc = validate({"starts": "netlogo", "arrival": "netlogo"})
    assert (sc.starts, sc.arrival, sc.uphillTies) == ("netlogo", "netlogo", "ordered")
    with pytest.raises(Exception, match="uphillTies: expected one of ordered, netlogo"):
        validate({"uphillTies": "random"})


@pytest.mark.parametrize("model", ["firefly", "ant"])
def test_batch_engine_equals_reference_with_the_netlogo_options(model):
    rnd = random.Random(3)
    scs, seeds = [], []
    every = {k: "netlogo" for k in CHOICES}
    for j in range(8):
        # the first: the netlogo scenario's world too (wrapping), the same compile
        opts = {**every, "wrap": j == 0} if j < 2 else {k: rnd.choice(CHOICES[k]) for k in CHOICES}
        scs.append(validate({"movementModel": model, "fieldDefiance": rnd.choice([0, 1, 2]),
                             "sigRadius": rnd.choice([2, 5, 8]), "maxTicks": 1200,
                             "object": rnd.choice(["bar", "L", "X"]), **opts}))
        seeds.append(rnd.randrange(10 ** 6))
    got = assert_same(scs, seeds)
    assert any(r.delivered for r in got)


def test_an_object_against_the_wall_is_planned_round_it_not_retried_forever():
    # seed 10, arrival "netlogo": every step that brings the nearest carrier
    # closer to home pushed the object off the arena, and the host retried them
    # until maxTicks; it now plans round the edge (way_home) and delivers
    sc = Scenario(arrival="netlogo", maxTicks=3000)
    res = Engine(sc, 10).run()
    assert res.summary()["outcome"] == "delivered"
    assert res.coordinator.closed == frozenset()       # the edge planner took over
    # a run that is never walled keeps the greedy rule
    other = Engine(Scenario(arrival="netlogo", maxTicks=3000), 1).run()
    assert other.delivered and other.coordinator.closed is None
