"""The hand-vectorised thesis engine, a documented specialisation
(docs/performance.md), held by the same differential harness as the
compiled batch engine: summaries and every robot's pose at every tick equal
the reference engine's."""

import pytest

from sim_backend import objects
from sim_backend.engine import Engine
from sim_backend.errors import EngineError
from sim_backend.scenario import validate
from sim_backend.vector_engine import VectorEngine, run_batch, run_batch_results
from tests.harness import assert_same, count_pushes, mixed_scenarios


def same(scs, seeds, until="delivered"):
    # the vector engine keeps positions, not FSM states, per tick
    return assert_same(scs, seeds, until=until, engine=VectorEngine, states=False)


@pytest.mark.parametrize("model", ["firefly", "ant"])
def test_every_object_identical(model):
    scs, seeds = [], []
    for obj in sorted(objects.SHAPES):
        sc = validate({"movementModel": model, "object": obj})
        for seed in (1, 2, 3):
            scs.append(sc)
            seeds.append(seed)
    same(scs, seeds)


@pytest.mark.parametrize("model", ["firefly", "ant"])
def test_many_seeds_identical(model):
    sc = validate({"movementModel": model})
    seeds = list(range(100, 124))              # 24 seeds in one batch
    same([sc] * len(seeds), seeds)


def test_mixed_parameters_in_one_batch():
    """Runs stop at different ticks and the batch is compacted while others go on."""
    same(*mixed_scenarios())


def test_until_converged_matches_reference_stopped_at_convergence():
    sc = validate({"movementModel": "ant", "object": "X"})
    seeds = list(range(1, 9))
    same([sc] * len(seeds), seeds, until="converged")


def test_one_scenario_many_seeds_and_results():
    sc = validate({})
    a = run_batch(sc, [5, 6, 7])
    b = [r.summary() for r in run_batch_results([sc, sc, sc], [5, 6, 7])]
    assert a == b == [Engine(sc, s).run().summary() for s in (5, 6, 7)]
    assert run_batch(sc, []) == []


def test_refuses_another_behaviour():
    with pytest.raises(EngineError, match="thesis behaviour only"):
        VectorEngine([(validate({"behaviour": "aggregate"}), 1)])


@pytest.mark.parametrize("crowd", ["yield", "block"])
def test_both_crowd_rules_identical_in_a_dense_swarm(crowd):
    """crowd "yield" (the default) and "block": 150 robots crowd the object,
    so robots stand in the carried group's way and (yield) step aside."""
    sc = validate({"agents": 150, "crowd": crowd, "maxTicks": 1500})
    got = same([sc, sc.replace(movementModel="ant")], [1, 2])
    if crowd == "yield":
        assert all(r.delivered for r in got)


def test_a_push_along_the_crowd_identical(monkeypatch):
    """300 robots in the default arena: robots hemmed in by the crowd are
    pushed along it (kernel._chain), and the vector engine, which hands
    make_way only the robots within CHAIN_DEPTH of the way, moves them as the
    reference does."""
    pushes = count_pushes(monkeypatch)
    sc = validate({"agents": 300, "maxTicks": 400})
    got = same([sc, sc], [5, 6])
    assert all(r.delivered for r in got)
    assert any(k >= 0 for k in pushes)
