"""The batch engine (sim_backend/batch/soa.py) runs the behaviour's own
source, transformed and compiled, and equals the reference engine bit for bit.

The differential harness runs every registered behaviour, both movement
models and every object: every robot's pose and FSM state at every tick and
the whole summary must match sim_backend.engine.Engine. The single-source
test changes one rule in a copy of a behaviour and shows that both engines
change, identically: there is no second copy of any rule to forget.
"""


import pytest

from sim_backend import registry
from sim_backend import objects
from sim_backend.batch.soa import SoaEngine, run_batch, run_batch_results
from sim_backend.errors import EngineError
from sim_backend.scenario import validate
from sim_backend.world import World
from tests.harness import (arena_scenarios, assert_same, count_pushes, mixed_scenarios,
                           reference, wrap_scenarios)



@pytest.mark.parametrize("behaviour", sorted(registry.names()))
@pytest.mark.parametrize("model", ["firefly", "ant"])
@pytest.mark.parametrize("activation", ["sync", "netlogo"])
def test_every_behaviour_model_and_object_identical(behaviour, model, activation):
    scs, seeds = [], []
    for j, obj in enumerate(sorted(objects.SHAPES)):
        scs.append(validate({"behaviour": behaviour, "movementModel": model, "object": obj,
                             "maxTicks": 3000, "activation": activation}))
        seeds.append(1 + j % 2)         # one run of each combination, the seeds alternate
    got = assert_same(scs, seeds)
    assert any(r.delivered for r in got), "no run reached its goal: a weak comparison"


@pytest.mark.parametrize("extra", [
    {"movementModel": "levy"}, {"movementModel": "levy", "levyMu": 1.2},
    {"movementModel": "moth"}, {"movementModel": "moth", "mothNoise": 0},
    {"movementModel": "frog"}, {"movementModel": "frog", "frogPause": 1, "frogJump": 9},
    {"movementModel": "ant", "antBlocked": "turn"},
    {"breeds": [{"count": 6, "movementModel": "levy", "rPower": 2.0},
                {"count": 8, "movementModel": "ant", "antBlocked": "turn"},
                {"count": 6, "movementModel": "moth", "mothNoise": 60}]},
], ids=lambda d: ",".join(f"{k}={v}" for k, v in d.items()))
def test_the_models_and_options_identical(extra):
    """The thesis behaviour's extra movement models and antBlocked."""
    scs = [validate({**extra, "object": obj, "maxTicks": 1500}) for obj in ("bar", "L")]
    got = assert_same(scs, [1, 2])
    assert any(r.coordinator.converged_tick >= 0 for r in got), "nothing converged"


def test_many_seeds_and_mixed_parameters_in_one_batch():
    """Runs of one batch stop at different ticks (delivered or at maxTicks)
    while the others go on."""
    scs, seeds = mixed_scenarios()
    got = assert_same(scs, seeds)
    assert len({r.ticks for r in got}) > 5


def test_obstacles_several_objects_and_the_dynamic_field_identical():
    scs, seeds = arena_scenarios()
    got = assert_same(scs, seeds)
    assert sum(r.delivered for r in got) >= len(got) // 2, "few deliveries: a weak comparison"
    moved = [r for r in got if r.delivered and r.scenario.field == "dynamic"]
    assert moved, "no dynamic-field run delivered"


def test_a_wrapping_world_identical():
    """wrap = true: moves, probes, claims, uphill and the field on the torus."""
    scs, seeds = wrap_scenarios()
    got = assert_same(scs, seeds)
    assert sum(r.delivered for r in got) >= len(got) // 2, "few deliveries: a weak comparison"


def test_until_converged_stops_where_the_reference_stops():
    sc = validate({"movementModel": "ant"})
    got = assert_same([sc] * 4, [5, 6, 7, 8], until="converged")
    assert all(r.coordinator.converged_tick == r.ticks for r in got if r.ticks < sc.maxTicks)


def test_summaries_of_run_batch_keep_input_order_across_behaviours():
    a = validate({"behaviour": "aggregate"})
    t = validate({})
    sums = run_batch([t, a, t], [3, 3, 4])
    assert [s["seed"] for s in sums] == [3, 3, 4]
    assert "largest" in sums[1] and "largest" not in sums[0]
    assert sums[0] == reference(t, 3).summary()


def test_run_batch_summarises_without_the_grids_back():
    """run_batch leaves a finished run's grids as the run began (a summary
    reads none of them): its summaries are those of results whose worlds got
    their grids back, with obstacles, decoys, drawn objects, a dynamic field,
    another behaviour and runs ending at different ticks."""
    scs, seeds = arena_scenarios()
    more, more_seeds = mixed_scenarios()
    scs, seeds = scs + more, seeds + more_seeds
    kept = run_batch_results(scs, seeds)
    assert run_batch(scs, seeds) == [r.summary() for r in kept]
    # what the flag leaves out: the grids as they began, where the runs
    # changed them
    sc = validate({"maxTicks": 400})
    bare = SoaEngine([(sc, 1)], grids=False).run()[0].world
    full = SoaEngine([(sc, 1)]).run()[0].world
    start = World(sc, 1)
    assert (bare.field, bare.stamp, bare.occ) == (start.field, start.stamp, start.occ)
    assert full.stamp != start.stamp
    assert (bare.xs, bare.ys, bare.object_cells) == (full.xs, full.ys, full.object_cells)


def test_bad_batches_get_a_named_error():
    with pytest.raises(EngineError, match="at least one run"):
        SoaEngine([])
    with pytest.raises(EngineError, match="one behaviour"):
        SoaEngine([(validate({}), 1), (validate({"behaviour": "aggregate"}), 1)])


def test_rules_changed_in_the_source_change_both_engines_identically(tmp_path):
    """Single source: aggregate's scaffold edited outside the repository (a
    state only the host's NUDGE leads to, a seventh constructor argument, the
    host's own measure; tests/test_behaviour_folder.spread_behaviour, the
    behaviour hil_tests/test_own_behaviour.py checks step by step). Both
    engines must follow the edited source, and the runs leave the original's."""
    from firmware_logic import messages as msg
    from tests.test_behaviour_folder import spread_behaviour
    active, schema = list(msg.ACTIVE), dict(msg.SCHEMA)
    try:
        spread = spread_behaviour(tmp_path)
        original = validate({"behaviour": "aggregate", "maxTicks": 400})
        changed = validate({"behaviour": str(spread), "maxTicks": 400})
        seeds = [1, 2]
        got = assert_same([changed] * 2, seeds)           # batch == reference on the edit
    finally:
        msg.ACTIVE[:] = active
        msg.SCHEMA.clear()
        msg.SCHEMA.update(schema)
    for seed, b in zip(seeds, got):
        assert b.summary()["nudges"] >= 1, seed          # the edit ran
        before = reference(original, seed)
        assert b.trajectories != before.trajectories[:len(b.trajectories)], seed


def test_a_push_along_the_crowd_identical(monkeypatch):
    """300 robots in the default arena: robots in the carried object's way
    with no free neighbour are pushed along the crowd (kernel._chain, crowd
    "yield"); the batch engine pushes them as the reference does."""
    sc = validate({"agents": 300, "maxTicks": 400})
    scs, seeds = [sc, sc], [5, 6]
    with monkeypatch.context() as m:             # the transform reads the real kernel
        pushes = count_pushes(m)
        refs = [reference(s, seed) for s, seed in zip(scs, seeds)]
    assert any(k >= 0 for k in pushes)             # the reference pushed
    got = assert_same(scs, seeds, refs=refs)
    assert all(r.delivered for r in got)
