"""The scenario key `wrap`: a toroidal search phase as
NetLogo's default world, a bounded transport phase (docs/tick-semantics.md)."""

import subprocess
import sys

import pytest

from firmware_logic import fixedpoint as fx
from firmware_logic.hal import NOTHING, OBJECT, WALL
from sim_backend import kernel
from sim_backend.errors import ScenarioError
from sim_backend.kernel import BLUE
from sim_backend.scenario import validate
from sim_backend.world import World

EAST, WEST, NORTH = 90, 270, 0


def _world(wrap, **keys):
    sc = validate({"agents": 2, "objectX": 0, "objectY": 0, "objectWeight": 1.0,
                   "wrap": wrap, **keys})
    return World(sc, 1)


def _place(w, i, px, py):
    w.xs[i] = px * fx.ONE
    w.ys[i] = py * fx.ONE
    w.recount()


def _patch(w, i):
    return fx.patch(w.xs[i]), fx.patch(w.ys[i])


@pytest.mark.parametrize("wrap, heading, start, end", [
    (True, EAST, (18, 5), (-18, 5)),      # off the east edge onto the west
    (True, WEST, (-18, 5), (18, 5)),
    (True, NORTH, (-5, 18), (-5, -18)),
    (False, EAST, (18, 5), (18, 5)),      # the bounded arena keeps it in
])
def test_a_move_off_the_edge_wraps_only_when_the_world_wraps(wrap, heading, start, end):
    for act in ("sync", "netlogo"):
        w = _world(wrap, activation=act)
        _place(w, 1, *start)
        w.mv_on[1], w.mv_h[1], w.mv_step[1] = 1, heading, fx.ONE
        if act == "sync":
            w.apply(1)
        else:
            w.apply_robot(1)
        assert _patch(w, 1) == end, act
        assert w.occ[w.idx(*end)] == 1


def test_a_probe_and_a_claim_see_across_the_edge():
    w = _world(True)
    _place(w, 1, -18, 0)
    w.obj[w.idx(18, 0)] = kernel.YELLOW             # a segment on the far side
    body = kernel.probe(w.grid, w.run, 0, w.xs[1], w.ys[1], WEST)
    assert body == OBJECT
    assert kernel.ahead_cell(w.w, w.n, w.xs[1], w.ys[1], WEST, w.rules) == w.idx(18, 0)
    b = _world(False)
    _place(b, 1, -18, 0)
    assert kernel.probe(b.grid, b.run, 0, b.xs[1], b.ys[1], WEST) == WALL
    assert kernel.probe(w.grid, w.run, 0, w.xs[1], w.ys[1], NORTH) == NOTHING


def test_the_field_is_painted_on_the_torus_and_uphill_follows_it():
    w = _world(True)
    w.signal(18, 0)                                  # a beacon on the east edge
    assert w.field[w.idx(-18, 0)] == 5               # one patch on, round the edge
    assert w.field[w.idx(-17, 0)] == 3
    total = sum(w.field)
    b = _world(False)
    b.signal(18, 0)
    assert b.field[b.idx(-18, 0)] == 0
    assert sum(b.field) < total                      # the bounded arena loses the far half
    w.signal(18, 0, sign=-1)
    assert sum(w.field) == 0                         # and it comes off whole
    w.signal(18, 0)
    _place(w, 1, -18, 0)
    assert w.uphill(1) == WEST                       # uphill looks round the edge
    _place(b, 1, -18, 0)
    assert b.uphill(1) == -1


def test_the_carried_object_stays_inside_the_arena():
    """A holder of the bar carries it east: one step to the edge, then the
    next step, which would cross it, is refused."""
    w = _world(True, objectX=9, objectY=0, agents=2)
    assert max(x for x, _ in w.object_cells) == 17
    _place(w, 0, 17, 2)
    k = w.idx(17, 1)
    w.obj[k], w.owner[k], w.held[0] = BLUE, 1, k
    for tick, end in ((1, 18), (2, 18)):
        w.carry_on[0], w.carry_dx[0], w.carry_dy[0] = 1, 1, 0
        w.apply(tick)
        assert max(x for x, _ in w.object_cells) == end
        assert _patch(w, 0) == (end, 2)
    assert min(x for x, _ in w.object_cells) == 11     # never wrapped to the west edge


@pytest.mark.parametrize("raw, message", [
    ({"wrap": "yes"}, "wrap: expected true or false, got 'yes'"),
    ({"wrap": True, "worldSize": 10, "sigRadius": 11, "objectX": 0, "objectY": 0,
      "homeX": -8, "homeY": -8}, "wrap: sigRadius 11 exceeds worldSize 10"),
])
def test_bad_wrap_scenarios_get_one_line_errors(raw, message):
    with pytest.raises(ScenarioError) as err:
        validate(raw)
    assert message in str(err.value) and "\n" not in str(err.value)


def test_a_wrapping_run_delivers_and_robots_crossed_an_edge():
    """A whole run in the reference engine: the swarm crosses the edges while
    it searches, and the object still comes home."""
    from sim_backend.engine import Engine
    sc = validate({"wrap": True, "movementModel": "firefly", "maxTicks": 4000})
    crossed = False
    for seed in (1, 2, 3):
        e = Engine(sc, seed, record_trajectories=True)
        r = e.run()
        assert r.delivered, seed
        for (x0, y0), (x1, y1) in zip(r.trajectories, r.trajectories[1:]):
            if any(abs(fx.patch(a) - fx.patch(b)) > 1 for a, b in zip(x0 + y0, x1 + y1)):
                crossed = True           # a jump of a whole arena: across an edge
    assert crossed, "no robot crossed an edge: the test shows nothing"


def test_scenarios_lists_the_wrap_key():
    p = subprocess.run([sys.executable, "-m", "bridge.cli", "scenarios"], capture_output=True,
                       text=True, check=True)
    line = next(ln for ln in p.stdout.splitlines() if ln.strip().startswith("wrap "))
    assert "False" in line and "false | true" in line


def test_a_mission_with_a_real_body_refuses_wrap():
    from bridge.bodies import BodyURLError, parse_body_url
    from bridge.mission import MixedMission
    sc = validate({"wrap": True})
    with pytest.raises(BodyURLError, match="wrap = true needs every robot simulated"):
        MixedMission(sc, 1, {1: parse_body_url("khepera://loop://")})
