"""The arena the user draws: objects and obstacles in a scenario, their
one-line validation errors, transport round obstacles, the way home."""

import pytest

from firmware_logic.behaviours.thesis.coordinator import way_home
from sim_backend import objects
from sim_backend.engine import Engine
from sim_backend.errors import ScenarioError
from sim_backend.kernel import OBSTACLE, YELLOW
from sim_backend.scenario import load, validate
from sim_backend.world import World

CRATE = {"objects": [{"name": "crate", "art": "###\n#..\n###", "at": [4, 2],
                      "weight": 3.0}]}


def test_art_rows_top_to_bottom():
    assert sorted(objects.art_cells("#.\n.#\n")) == [(0, 1), (1, 0)]
    assert set(objects.art_cells(objects.art("L"))) == {
        (x - 1, y) for x, y in objects.offsets("L")}
    with pytest.raises(ValueError, match="'x'"):
        objects.art_cells("#x")


def test_drawn_object_is_the_target_and_round_trips():
    sc = validate(CRATE)
    assert sc.object == "crate" and sc.objectX == 4 and sc.objectWeight == 3.0
    assert sc.replace(agents=30).objects == sc.objects
    w = World(sc, 1)
    assert sorted(w.object_cells) == sorted(
        (4 + x, 2 + y) for x, y in [(0, 0), (1, 0), (2, 0), (0, 1), (0, 2), (1, 2), (2, 2)])


def test_density_gives_weight():
    sc = validate({"objects": [{"shape": "square", "at": [0, 0], "density": 0.25}]})
    assert sc.objectWeight == 4.0         # 16 cells x 0.25


def test_world_draws_decoys_and_obstacles():
    sc = load("decoy").replace(obstacles=[{"cells": [[0, 0], [0, 1]], "at": [-5, -5]}])
    w = World(sc, 3)
    assert w.obj[w.idx(-12, 6)] == YELLOW and (-12, 6) in w.decoy_cells
    assert (-12, 6) not in w.object_cells
    assert w.obj[w.idx(-5, -4)] == OBSTACLE


BAD = [
    ({"objects": [{"art": "#", "cells": [[0, 0]], "at": [0, 0]}]},
     "objects[0]: give exactly one of art, cells or shape"),
    ({"objects": [{"art": "#?", "at": [0, 0]}]}, "objects[0].art: character '?'"),
    ({"objects": [{"cells": [[0, 0], [0, 0]], "at": [0, 0]}]},
     "objects[0].cells: cell [0, 0] is given twice"),
    ({"objects": [{"shape": "bar", "at": [0, 0], "colour": 1}]},
     "objects[0]: unknown key 'colour'"),
    ({"objects": [{"shape": "bar", "at": [0, 0.5]}]}, "objects[0].at: expected [x, y]"),
    ({"objects": [{"shape": "bar", "at": [0, 0], "weight": -1}]}, "objects[0].weight:"),
    ({"objects": [{"shape": "bar", "at": [0, 0], "weight": 2, "density": 0.5}]},
     "objects[0]: give weight or density, not both"),
    ({"objects": [{"shape": "bar", "at": [0, 0], "target": "yes"}]}, "objects[0].target:"),
    ({"objects": [{"shape": "bar", "at": [0, 0]}, {"shape": "bar", "at": [0, 5]}]},
     "objects: exactly one object must have target = true"),
    ({"objects": [{"shape": "bar", "target": True}, {"shape": "bar", "target": False}]},
     "objects[1].at: required"),
    ({"objects": [{"name": "a", "shape": "bar", "at": [0, 0], "target": True},
                  {"name": "a", "shape": "bar", "at": [0, 5]}]}, "objects[1].name: 'a'"),
    ({"objects": [{"shape": "bar", "at": [12, 0]}]}, "objects[0].at: 'object0' at [12, 0]"),
    ({"objects": [{"shape": "bar", "at": [0, 0], "target": True},
                  {"shape": "bar", "at": [0, 1]}]}, "overlaps objects[0]"),
    ({"objects": [{"shape": "bar", "at": [0, 0]}],
      "obstacles": [{"art": "####", "at": [3, 1]}]}, "overlaps obstacles[0]"),
    ({"objects": [{"shape": "bar", "at": [0, 0]}],
      "obstacles": [{"art": "#"}]}, "obstacles[0].at: required"),
    ({"objects": [{"shape": "bar", "at": [0, 0]}],
      "obstacles": [{"art": "#", "at": [-15, -15]}]}, "obstacles[0].at: 'obstacle0' covers home"),
    ({"objects": [{"shape": "bar", "at": [-14, -12]}]}, "within 4 patches of home"),
    ({"objects": [{"shape": "bar", "at": [0, 0], "weight": 30}]},
     "objects[0].weight: weight 30 is more than all 20 robots can hold together"),
    # a single cell: at most one robot at a time can hold it, thesis 6.1.5
    ({"objects": [{"cells": [[0, 0]], "at": [0, 0], "weight": 2}]},
     "only 1 can surround"),
    # a square walled in on three sides: only the four on its open side can hold it
    ({"objects": [{"shape": "square", "at": [0, 0], "density": 0.5}],
      "obstacles": [{"art": "#....#\n#....#\n#....#\n#....#\n#....#\n######", "at": [0, 0]}],
      "agents": 30}, "objects[0].density: weight 8 needs 8 robots holding, but "
                     "only 4 can surround"),
    ({"objects": [{"shape": "bar", "at": [0, 0]}],
      "obstacles": [{"art": "#" * 37, "at": [-18, -2]}]}, "objects[0].at: 'object0' has no way home"),
    # a thick ring: the 12 segments round its hole cannot be reached from outside
    ({"objects": [{"art": "#######\n#######\n##...##\n##...##\n##...##\n#######\n#######",
                   "at": [0, 0], "weight": 30}], "agents": 40}, "only 24 can surround"),
    ({"objects": [{"shape": "bar", "at": [0, 0]}], "object": "L"}, "object: set by [[objects]]"),
    ({"objects": [{"shape": "bar", "at": [0, 0]}], "agents": 5000},
     "agents: 5000 robots crowd a 37-patch arena"),
    ({"objects": [{"shape": "bar", "at": [0, 0], "density": 900}]},
     "objects[0].density: 900 x 16 cells = weight 14400"),
    ({"crowd": "push"}, "crowd: expected one of block, yield"),
    ({"field": "moving"}, "field: expected one of static, dynamic"),
    ({"obstacles": "wall"}, "obstacles: expected an array of tables"),
]


@pytest.mark.parametrize("raw,needle", BAD)
def test_each_bad_table_is_one_line_naming_table_and_key(raw, needle):
    with pytest.raises(ScenarioError) as e:
        validate(raw)
    msg = str(e.value)
    assert needle in msg, msg
    assert "\n" not in msg


def test_obstacles_with_the_flat_object():
    sc = validate({"object": "bar", "objectX": 2, "objectY": 4,
                   "obstacles": [{"art": "#####", "at": [-12, 0]}]})
    assert sc.pieces()[0].name == "bar"


def test_way_home_goes_round_a_wall():
    # a 1-cell object at (0, 5), home at (0, -5), a wall y = 0 from x -5..5
    wall = {(x, 0) for x in range(-5, 6)}
    d = way_home(10, [(0, 5)], wall, [(0, 5)], 0, -5, 1, (0, 0))
    assert d[(0, 0)] == 10 + 2     # round the wall's end costs more than the straight 10
    for dx, dy in d:
        assert (dx, 5 + dy) not in wall
    closed = wall | {(x, 0) for x in range(-10, 11)}
    assert (0, 0) not in way_home(10, [(0, 5)], closed, [(0, 5)], 0, -5, 1, (0, 0))


def _never_overlaps(eng):
    w = eng.world
    closed = set(w.obstacle_cells) | set(w.decoy_cells)

    def check(snap):
        cells = w.object_cells
        assert not closed & set(cells), ("object on an obstacle", eng.tick)
        assert all(w.inside(x, y) for x, y in cells), ("object off the arena", eng.tick)
    return check


@pytest.mark.parametrize("name,seed", [("wall", 1), ("wall", 2), ("decoy", 4)])
def test_transport_round_obstacles_never_overlaps(name, seed):
    eng = Engine(load(name), seed)
    eng.observe(_never_overlaps(eng))
    res = eng.run()
    assert res.delivered, res.summary()["outcome"]
    assert res.summary()["outcome"] == "delivered"
    assert res.coordinator._home_reached()


def _coordinator_with_a_gap(stall_ticks=2000):
    """A one-cell object at (0, 5) held by a robot at (1, 5) (east of it),
    home at (0, -10), a wall along y = 0 with a one-patch gap at x = 0: the
    cell alone fits the gap, the cell with its carrier beside it does not."""
    from firmware_logic import messages as msg
    from firmware_logic.behaviours.thesis.coordinator import Coordinator
    wall = [(x, 0) for x in range(-18, 19) if x != 0]
    c = Coordinator(100, 0, -10, world_size=18, cells=[(0, 5)], blocked=wall,
                    stall_ticks=stall_ticks)
    c.on_message(1, msg.HELLO, (1, 100, 1), 1)
    c.on_message(1, msg.TOUCH, (1, 1, 5, 0, 5, 100), 2)
    return c


def test_no_path_home_stops_at_convergence_with_a_status():
    from firmware_logic import messages as msg
    c = _coordinator_with_a_gap()
    out = c.tick(2)
    assert c.converged_tick == 2 and c.stopped_tick == 2 and c.done()
    assert (msg.HOST, msg.HALT, (0,)) in out
    assert c.measures() == {"outcome": "no path home"}
    assert "no path home" in c.status()
    # the object's cells alone do have a way through the gap
    assert (0, 0) in way_home(18, [(0, 5)], set(c.closed), [(0, 5)], 0, -10, 16, (0, 0))


def test_a_transport_that_never_moves_stops_as_stalled():
    from firmware_logic import messages as msg
    from firmware_logic.behaviours.thesis.coordinator import Coordinator
    c = Coordinator(100, -15, -15, world_size=18, cells=[(5, 5)], stall_ticks=50)
    c.on_message(1, msg.HELLO, (1, 100, 1), 1)
    c.on_message(1, msg.TOUCH, (1, 5, 4, 5, 5, 100), 2)
    t = 2
    while not c.done() and t < 1000:
        c.tick(t)
        # the leader reports each step done but the object never moves
        c.on_message(1, msg.HEARTBEAT, (4, 5 * 256, 4 * 256, 0, c.step, 0), t)
        t += 1
    # converged at tick 2; transport ticks count from the first, tick 3
    assert c.measures() == {"outcome": "stalled"} and c.stopped_tick == 3 + 50


def test_decoy_touches_are_not_counted():
    res = Engine(load("decoy"), 2).run()
    c = res.coordinator
    decoy = set(res.world.decoy_cells)
    assert not decoy & set(c.segments_now())
    assert res.delivered


def test_scenario_dict_round_trips_through_validate():
    for name in ("crate", "decoy", "wall"):
        sc = load(name)
        assert validate(sc.to_dict()) == sc


def _carry_scene(crowd, blocker_at, third_at=(10, 10), field="static", more=()):
    """Robot 1 holds the bar's cell (1, 0) from (0, 0); robot 2 stands at
    blocker_at, robot 3 at third_at, robots 4... at `more`; robot 1 asks to
    carry the bar one patch south."""
    from firmware_logic import fixedpoint as fx
    from sim_backend.kernel import BLUE
    at = ((0, 0), blocker_at, third_at) + tuple(more)
    sc = validate({"objectX": 0, "objectY": 0, "agents": len(at), "crowd": crowd,
                   "objectWeight": 1.0, "field": field})
    w = World(sc, 1)
    w.xs[:] = [x * fx.ONE for x, _ in at]
    w.ys[:] = [y * fx.ONE for _, y in at]
    k = w.idx(1, 0)
    w.obj[k] = BLUE
    w.owner[k] = 1
    w.held[0] = k
    w.recount()
    w.carry_on[0], w.carry_dx[0], w.carry_dy[0] = 1, 0, -1
    w.beacon_set[0] = 1                               # the carrier's beacon lights
    w.apply(1)
    return w


def test_a_crowd_that_yields_steps_aside_for_the_carried_object():
    from firmware_logic import fixedpoint as fx
    blocked = _carry_scene("block", (4, -1))
    assert (1, 0) in blocked.object_cells            # the robot at (4, -1) blocks
    moved = _carry_scene("yield", (4, -1))
    assert (1, -1) in moved.object_cells and (1, 1) not in moved.object_cells
    # it stepped aside, in the carry's direction first, off the object's way
    assert (fx.patch(moved.xs[1]), fx.patch(moved.ys[1])) == (4, -2)
    assert (fx.patch(moved.xs[0]), fx.patch(moved.ys[0])) == (0, -1)   # the carrier came along
    # with its patch south taken, it steps to the first free neighbour in
    # N, NE, E, SE... order off the object's way: north and east are the
    # object's or on its way, so south-east
    w = _carry_scene("yield", (4, -1), (4, -2))
    assert (fx.patch(w.xs[1]), fx.patch(w.ys[1])) == (5, -2)
    assert (fx.patch(w.xs[2]), fx.patch(w.ys[2])) == (4, -2)


def test_a_robot_hemmed_in_by_the_crowd_is_pushed_along_it():
    """Robot 2 on (4, -1) stands in the carried bar's way (cells (1..8, 0..1),
    south) with every neighbour off the way taken by robots 3-5 (a crowd
    two deep). The nearest push along the crowd (kernel._chain): robot 3 on
    (3, -2) steps on to the free (2, -3), robot 2 into (3, -2); without it
    the step was blocked for good (the 10,000-robot stalls)."""
    from firmware_logic import fixedpoint as fx
    w = _carry_scene("yield", (4, -1), (3, -2), more=((4, -2), (5, -2)))
    assert (1, -1) in w.object_cells and (1, 1) not in w.object_cells
    got = [(fx.patch(x), fx.patch(y)) for x, y in zip(w.xs, w.ys)]
    assert got == [(0, -1), (3, -2), (2, -3), (4, -2), (5, -2)]
    assert all(w.stamp[w.idx(x, y)] == 1 for x, y in ((3, -2), (2, -3)))   # entered
    assert min(w.stamp) >= -1                   # the search left no mark behind


def test_the_push_along_the_crowd_finds_each_robot_a_scan_of_all_would(monkeypatch):
    """kernel._robot_at looks only at make_way's rb.near (the robots round
    the group's way); at every patch the push asks about it names the robot
    a scan of the run's every robot names, and robot 6, far off at
    (10, 10), is not among them."""
    from firmware_logic import fixedpoint as fx
    from sim_backend import kernel
    real = kernel._robot_at
    asked = []

    def checked(rb, run, r, px, py):
        every = next((-1 if rb.held[i] >= 0 else i for i in range(run.lo[r], run.hi[r])
                      if (fx.patch(rb.xs[i]), fx.patch(rb.ys[i])) == (px, py)), -1)
        near = list(rb.near[run.lo[r]:run.hi[r]]) + [-1]
        asked.append((real(rb, run, r, px, py), every, 5 in near[:near.index(-1)]))
        return asked[-1][0]
    monkeypatch.setattr(kernel, "_robot_at", checked)
    w = _carry_scene("yield", (4, -1), (3, -2), more=((4, -2), (5, -2), (10, 10)))
    assert (fx.patch(w.xs[1]), fx.patch(w.ys[1])) == (3, -2)     # pushed, as above
    assert asked and all(got == every for got, every, _ in asked)
    assert not any(far for _, _, far in asked)


def test_the_dynamic_field_moves_with_its_carrier():
    peak = {}
    for field in ("static", "dynamic"):
        w = _carry_scene("yield", (10, 10), field=field)
        best = max(range(len(w.field)), key=lambda k: w.field[k])
        peak[field] = (best % w.n - w.w, best // w.n - w.w)
        assert w.field[best] == 10 and sorted(w.field)[-2] < 10   # one beacon, no trace left
    assert peak == {"static": (0, 0), "dynamic": (0, -1)}


def test_cli_refuses_a_bad_drawn_scenario_in_one_line(tmp_path):
    import subprocess
    import sys
    f = tmp_path / "overlap.toml"
    f.write_text('[[objects]]\nshape = "bar"\nat = [0, 0]\n\n'
                 '[[obstacles]]\nart = "###"\nat = [2, 1]\n')
    p = subprocess.run([sys.executable, "-m", "bridge.cli", "run", "--scenario", str(f)],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 2
    assert p.stderr.strip() == ("touchswarm: error: objects[0].at: 'object0' overlaps "
                                "obstacles[0] at [2, 1]")


def test_scenarios_command_prints_each_shape_as_art():
    import subprocess
    import sys
    p = subprocess.run([sys.executable, "-m", "bridge.cli", "scenarios"],
                       capture_output=True, text=True, timeout=120)
    assert p.returncode == 0
    for name in objects.SHAPES:
        assert f"  {name}:\n" in p.stdout
    assert "    ########\n    ########\n" in p.stdout      # the bar
    for key in ("objects", "obstacles", "field", "crowd"):
        assert f"  {key} " in p.stdout


@pytest.mark.parametrize("name", ["crate", "decoy", "wall"])
def test_worked_examples_run_over_can_as_in_process(name, capsys):
    import json

    from bridge.cli import main
    outs = {}
    for link in ("inproc", "can"):
        assert main(["run", "--scenario", name, "--seed", "1", "--link", link, "--json"]) == 0
        outs[link] = json.loads(capsys.readouterr().out)
    assert outs["can"] == outs["inproc"]
    assert outs["can"]["outcome"] == "delivered"


def test_the_crowd_rule_cannot_change_a_run_until_convergence():
    """crowd acts only on the carried object, so the thesis's figures (runs
    stopped at convergence, `sweep --thesis`) are the same under either
    rule; after convergence the rules part (200 robots: block stalls)."""
    from sim_backend.batch.soa import run_batch_results
    runs = {}
    for crowd in ("yield", "block"):
        sc = validate({"agents": 150, "crowd": crowd, "maxTicks": 1500})
        got = run_batch_results([sc] * 3, [1, 2, 3], record_trajectories=True,
                                until="converged")
        assert all(r.coordinator.converged_tick > 0 for r in got)
        runs[crowd] = [(r.coordinator.converged_tick, r.summary()["touches"], r.trajectories)
                       for r in got]
    assert runs["yield"] == runs["block"]
    delivered = {}
    for crowd in ("yield", "block"):
        sc = validate({"agents": 200, "crowd": crowd, "maxTicks": 2500})
        delivered[crowd] = sum(r.delivered for r in run_batch_results(
            [sc] * 3, [1, 2, 3]))
    assert delivered == {"yield": 3, "block": 0}
