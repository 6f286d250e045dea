"""Differential test: the vectorised engine is bit-identical to the reference.

Every run outcome (the whole summary) and every robot's position at every
tick must match sim_backend.engine.Engine for the same scenario and seed.
"""

import random

import pytest

from sim_backend import objects
from sim_backend.engine import Engine, RunResult
from sim_backend.errors import ScenarioError
from sim_backend.scenario import validate
from sim_backend.vector_engine import run_batch, run_batch_results


def reference(sc, seed, until="delivered"):
    e = Engine(sc, seed, record_trajectories=True)
    if until == "delivered":
        r = e.run()
    else:
        while not (e.coordinator.converged_tick >= 0 or e.tick >= sc.maxTicks):
            e.step()
        r = RunResult(sc, seed, e.tick, e.world, e.coordinator, e.robots, e.trajectories)
    return r.summary(), r.trajectories


def assert_same(scs, seeds, until="delivered"):
    sums, trajs = run_batch(scs, seeds, trajectories=True, until=until)
    assert len(sums) == len(seeds)
    for sc, seed, s, t in zip(scs, seeds, sums, trajs):
        rs, rt = reference(sc, seed, until)
        assert s == rs, (sc, seed, {k: (rs[k], s[k]) for k in rs if rs[k] != s[k]})
        assert len(t) == len(rt) == rs["ticks"]
        for tick, (a, b) in enumerate(zip(rt, t), 1):
            assert a == b, (sc.name, sc.movementModel, sc.object, seed, "tick", tick)


@pytest.mark.parametrize("model", ["firefly", "ant"])
def test_every_object_identical(model):
    scs, seeds = [], []
    for obj in sorted(objects.SHAPES):
        sc = validate({"movementModel": model, "object": obj})
        for seed in (1, 2, 3):
            scs.append(sc)
            seeds.append(seed)
    assert_same(scs, seeds)


@pytest.mark.parametrize("model", ["firefly", "ant"])
def test_many_seeds_identical(model):
    sc = validate({"movementModel": model})
    seeds = list(range(100, 124))              # 24 seeds in one batch
    assert_same([sc] * len(seeds), seeds)


def test_mixed_parameters_in_one_batch():
    """Edge parameters (no defiance, zero span, zero radius, few and many robots,
    other arena sizes, runs that hit maxTicks) mixed in one batch, so runs stop
    at different ticks and the batch is compacted while others go on."""
    rnd = random.Random(11)
    scs, seeds = [], []
    while len(scs) < 24:
        d = {"movementModel": rnd.choice(["firefly", "ant"]),
             "object": rnd.choice(sorted(objects.SHAPES)),
             "fieldDefiance": rnd.choice([0, 1, 2, 5]),
             "sigRadius": rnd.choice([0, 1, 3, 5, 8]),
             "rPower": rnd.choice([0.5, 1.0, 1.25, 2.0, 5.0]),
             "agents": rnd.choice([3, 8, 20, 40]),
             "robotVisionSpan": rnd.choice([0, 10, 45, 180]),
             "worldSize": rnd.choice([15, 18, 25]),
             "maxTicks": 1500}
        try:
            sc = validate(d)
        except ScenarioError:
            continue
        scs.append(sc)
        seeds.append(rnd.randrange(10 ** 6))
    assert_same(scs, seeds)


def test_until_converged_matches_reference_stopped_at_convergence():
    sc = validate({"movementModel": "ant", "object": "X"})
    seeds = list(range(1, 9))
    assert_same([sc] * len(seeds), seeds, until="converged")


def test_one_scenario_many_seeds_and_results():
    sc = validate({})
    a = run_batch(sc, [5, 6, 7])
    b = [r.summary() for r in run_batch_results([sc, sc, sc], [5, 6, 7])]
    assert a == b == [Engine(sc, s).run().summary() for s in (5, 6, 7)]
    assert run_batch(sc, []) == []
