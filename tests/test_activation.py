"""Activation (scenario key `activation`): the synchronous tick (default) and
NetLogo's sequential `ask robots` (docs/tick-semantics.md, Activation).

Order matters on a tiny world where two robots head for the same patch: in
sync the tick's conflict rule gives it to the lower node; in netlogo the
first robot of the drawn order takes it and the second sees it taken. The
differential harness holds reference == batch for activation netlogo."""

import random

import pytest

from firmware_logic.behaviours.thesis import robot as R
from sim_backend import kernel
from sim_backend.engine import Engine
from sim_backend.errors import EngineError, ScenarioError
from sim_backend.scenario import validate
from tests.harness import assert_same, mixed_scenarios

# two ant robots that never turn (span 0), far from the object
TINY = {"agents": 2, "objectWeight": 2, "worldSize": 10, "objectX": -4, "objectY": 6,
        "homeX": -7, "homeY": -7, "movementModel": "ant", "robotVisionSpan": 0,
        "maxTicks": 50}


def two_robots_for_one_patch(activation, seed):
    """Node 1 at x 0.4 heading east, node 2 at x 1.6 heading west: one
    quarter step takes either into patch (1, 0). Returns the engine after
    one tick (one go iteration)."""
    e = Engine(validate({**TINY, "activation": activation}), seed)
    w = e.world
    w.xs[:] = [102, 410]                 # 0.4 and 1.6 patches in Q8
    w.ys[:] = [0, 0]
    w.recount()
    e.robots[0].heading = 90
    e.robots[1].heading = 270
    e.step()
    return e


def patch_x(e, i):
    return (e.world.xs[i] + 128) >> 8


def test_sync_gives_the_contested_patch_to_the_lower_node():
    for seed in range(1, 6):
        e = two_robots_for_one_patch("sync", seed)
        assert (patch_x(e, 0), patch_x(e, 1)) == (1, 2)
        assert e.world.xs[1] == 410                     # node 2's move failed


def test_netlogo_gives_the_contested_patch_to_the_first_in_the_drawn_order():
    firsts = set()
    for seed in range(1, 30):
        e = two_robots_for_one_patch("netlogo", seed)
        first, second = e.world.order
        firsts.add(first)
        assert patch_x(e, first) == 1
        # the second saw the first there (HeadCarefully: a robot ahead) and stayed
        start = [102, 410][second]
        assert e.world.xs[second] == start
    assert firsts == {0, 1}, "the order never put node 2 first: a weak test"


def test_the_order_is_drawn_afresh_every_iteration_from_the_run_seed():
    sc = validate({**TINY, "agents": 6, "objectWeight": 3})
    e = Engine(sc.replace(activation="netlogo"), 7)
    orders = [tuple(e.world.draw_order()) for _ in range(40)]
    assert all(sorted(o) == list(range(6)) for o in orders)
    assert len(set(orders)) > 30
    again = Engine(sc.replace(activation="netlogo"), 7)
    assert orders == [tuple(again.world.draw_order()) for _ in range(40)]
    other = Engine(sc.replace(activation="netlogo"), 8)
    assert orders != [tuple(other.world.draw_order()) for _ in range(40)]


def test_a_robot_steps_once_in_search_and_one_plus_defiance_times_in_a_field():
    for fd in (0, 2, 5):
        sc = validate({"movementModel": "firefly", "fieldDefiance": fd,
                       "activation": "netlogo", "maxTicks": 400})
        e = Engine(sc, 3)
        assert (e.world.run.field_state[0], e.world.run.extra_steps[0]) == (R.FIELD, fd)
        seen = {R.SEARCH: 0, R.FIELD: 0}
        while not e.finished():
            before = [(r.state, r.ticks) for r in e.robots]
            e.step()
            for (state, ticks), r in zip(before, e.robots):
                if state == r.state and state in seen:
                    assert r.ticks - ticks == kernel.turn_steps(e.world.run, 0, state)
                    seen[state] += 1
        assert seen[R.SEARCH] > 100 and seen[R.FIELD] > 20, seen


def test_a_touch_is_held_and_signalled_in_the_iteration_it_happens():
    """LookForObject holds at once and go's Signal follows the ask: the
    finder's beacon field is in the world at the end of the iteration in
    which it touched."""
    sc = validate({"activation": "netlogo", "maxTicks": 3000})
    e = Engine(sc, 4)
    while not e.finished() and not any(r.state == R.HOLD for r in e.robots):
        e.step()
    assert any(r.state == R.HOLD for r in e.robots)
    assert not any(r.state == R.GRASP for r in e.robots)
    assert max(e.world.field) > 0


def test_the_same_seed_gives_the_same_run_and_another_seed_another():
    sc = validate({"activation": "netlogo", "movementModel": "ant", "maxTicks": 1500})
    a = Engine(sc, 21, record_trajectories=True).run()
    b = Engine(sc, 21, record_trajectories=True).run()
    c = Engine(sc, 22, record_trajectories=True).run()
    assert a.summary() == b.summary() and a.trajectories == b.trajectories
    assert a.trajectories != c.trajectories


def test_summaries_report_convergence_in_go_iterations_and_in_moves():
    sync = Engine(validate({"fieldDefiance": 4}), 2).run().summary()
    assert sync["activation"] == "sync"
    assert sync["converged_moves"] == float(sync["converged_tick"])
    net = Engine(validate({"fieldDefiance": 4, "activation": "netlogo"}), 2).run().summary()
    assert net["activation"] == "netlogo"
    # a field robot takes 5 steps an iteration, a searching one 1, a holder 1
    assert net["converged_tick"] < net["converged_moves"] < 5 * net["converged_tick"]


@pytest.mark.parametrize("activation", ["netlogo", "sync"])
def test_reading_a_big_runs_robots_ahead_changes_nothing(monkeypatch, activation):
    """A run of kernel.WARM_MIN robots fetches each robot's row and patches a
    few turns ahead of its turn, and (sync) the cells its move enters a few
    moves ahead (kernel.prefetch: a cache hint when compiled, nothing here):
    the run is the one without, robots on the arena's edge rows among them."""
    sc = validate({"agents": kernel.WARM_MIN, "worldSize": 24, "objectWeight": 3,
                   "activation": activation, "maxTicks": 20})

    def run():
        e = Engine(sc, 5)
        for _ in range(6):
            e.step()
        w = e.world
        return (list(w.xs), list(w.ys), list(w.held), list(w.field), list(w.obj),
                [r.state for r in e.robots], [r.heading for r in e.robots])

    warm = run()
    monkeypatch.setattr(kernel, "WARM_MIN", kernel.WARM_MIN + 1)
    assert run() == warm
    rows = {(y + 128) >> 8 for y in warm[1]}
    assert {-24, 24} <= rows, "no robot on an edge row: a weak test"


@pytest.mark.parametrize("model", ["firefly", "ant"])
def test_batch_equals_reference_under_netlogo_activation(model):
    scs, seeds = [], []
    for obj in ("bar", "L", "X"):
        for fd in (0, 2):
            sc = validate({"movementModel": model, "object": obj, "fieldDefiance": fd,
                           "activation": "netlogo", "maxTicks": 2500})
            scs.append(sc)
            seeds.append(len(seeds) + 1)
    got = assert_same(scs, seeds)
    assert any(r.delivered for r in got), "no run delivered: a weak comparison"
    assert all(r.summary()["activation"] == "netlogo" for r in got)


def test_batch_mixes_both_activations_and_every_netlogo_option_in_one_batch():
    scs, seeds = mixed_scenarios(n=16, seed=5)
    rnd = random.Random(9)
    mixed = []
    for sc in scs:
        ch = {"activation": rnd.choice(["sync", "netlogo"])}
        for k in ("signalMode", "uphillTies", "leaderField", "starts"):
            ch[k] = rnd.choice([sc.to_dict()[k], "netlogo"])
        mixed.append(sc.replace(**ch))
    assert {sc.activation for sc in mixed} == {"sync", "netlogo"}
    assert_same(mixed, seeds)


def test_bad_activation_values_get_a_one_line_error():
    for bad in ("async", 1, "", None):
        with pytest.raises(ScenarioError) as err:
            validate({"activation": bad})
        assert "activation: expected one of sync, netlogo" in str(err.value)
        assert "\n" not in str(err.value)


def test_sweep_thesis_with_netlogo_activation_writes_both_units_and_the_thesis_figures(
        tmp_path, capsys):
    from bridge.cli import main
    from sim_backend import sweep
    rc = main(["sweep", "--thesis", "--activation", "netlogo", "--seeds", "1",
               "--executor", "inline", "--set", "maxTicks=400", "--out", str(tmp_path)])
    assert rc == 0
    for name in ("graph1", "graph4", "fig22_bar", "graph1_units", "fig22_bar_thesis",
                 "fig23_L_plus_thesis", "fig24_X_thesis"):
        assert (tmp_path / f"{name}.png").stat().st_size > 1000, name
    rows = sweep.read_csv(tmp_path / "sweep.csv")
    assert {r["activation"] for r in rows} == {"netlogo"}
    done = [r for r in rows if r["converged_tick"]]
    assert done and all(float(r["converged_moves"]) >= float(r["converged_tick"])
                        for r in done)
    assert all(len(r["touches"].split()) == len(r["segments"].split()) for r in rows)
    assert any(float(r["converged_moves"]) > float(r["converged_tick"]) for r in done)


def test_sweep_activation_given_twice_is_a_usage_error(capsys):
    from bridge.cli import main
    assert main(["sweep", "--grid", "agents=5,6", "--activation", "netlogo",
                 "--set", "activation=sync"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--activation" in err[0]
    with pytest.raises(SystemExit) as exit_:
        main(["sweep", "--grid", "agents=5,6", "--activation", "fast"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--activation: invalid choice: 'fast'" in err[0]


def test_the_sync_apply_seam_of_real_robots_refuses_netlogo_activation():
    """bridge/mission.py and the tether emulator end a tick through
    Engine._apply (real robots act in parallel): under netlogo it refuses."""
    e = Engine(validate({**TINY, "activation": "netlogo"}), 1)
    with pytest.raises(EngineError, match="activation sync only"):
        e._apply()
    Engine(validate(TINY), 1)._apply()          # sync: the ordinary end of a tick
