"""The differential harness the batch engine (sim_backend/batch/soa.py) is
held to: the reference engine's summary, every robot's pose and FSM state at
every tick and the final world, bit for bit."""

import random

from sim_backend import objects
from sim_backend.batch.soa import run_batch_results
from sim_backend.engine import Engine
from sim_backend.errors import ScenarioError
from sim_backend.scenario import validate


def reference(sc, seed, until="delivered"):
    return Engine(sc, seed, record_trajectories=True, until=until).run()


def assert_same(scs, seeds, until="delivered", states=True, refs=None):
    """Run the batch in the batch engine and compare every run with the
    reference; return the batch's RunResults. refs: the reference runs
    already made (`reference`, e.g. under a counter that proves a rule ran),
    so none is run twice."""
    got = run_batch_results(scs, seeds, record_trajectories=True, until=until)
    assert len(got) == len(seeds)
    if refs is None:
        refs = [reference(sc, seed, until) for sc, seed in zip(scs, seeds)]
    assert len(refs) == len(seeds)
    for sc, seed, b, r in zip(scs, seeds, got, refs):
        rs, bs = r.summary(), b.summary()
        assert bs == rs, (sc.behaviour, seed, {k: (rs[k], bs[k]) for k in rs if rs[k] != bs[k]})
        assert len(b.trajectories) == len(r.trajectories) == r.ticks
        for tick, (a, c) in enumerate(zip(r.trajectories, b.trajectories), 1):
            assert a == c, (sc.behaviour, sc.movementModel, sc.object, seed, "pose, tick", tick)
        if states:
            assert len(b.states) == r.ticks
            for tick, (a, c) in enumerate(zip(r.states, b.states), 1):
                assert a == c, (sc.behaviour, sc.movementModel, sc.object, seed, "state", tick)
            assert (b.world.field, b.world.obj, b.world.occ) == (r.world.field, r.world.obj,
                                                                r.world.occ)
    return got


def mixed_scenarios(n=24, seed=11):
    """Edge parameters (no defiance, zero span, zero radius, few and many
    robots, other arena sizes, runs that hit maxTicks), so the runs of one
    batch stop at different ticks while the others go on."""
    rnd = random.Random(seed)
    scs, seeds = [], []
    while len(scs) < n:
        d = {"movementModel": rnd.choice(["firefly", "ant"]),
             "object": rnd.choice(sorted(objects.SHAPES)),
             "fieldDefiance": rnd.choice([0, 1, 2, 5]),
             "sigRadius": rnd.choice([0, 1, 3, 5, 8]),
             "rPower": rnd.choice([0.5, 1.0, 1.25, 2.0, 5.0]),
             "agents": rnd.choice([3, 8, 20, 40]),
             "robotVisionSpan": rnd.choice([0, 10, 45, 180]),
             "worldSize": rnd.choice([15, 18, 25]),
             "maxTicks": 700}
        try:
            sc = validate(d)
        except ScenarioError:
            continue
        scs.append(sc)
        seeds.append(rnd.randrange(10 ** 6))
    return scs, seeds


def arena_scenarios():
    """Drawn objects, decoys, obstacles and the dynamic field, in
    both movement models and both fields, and the aggregate behaviour among
    obstacles: one run of each, the seeds alternating."""
    from sim_backend.scenario import load
    scs = []
    for name in ("crate", "decoy", "wall"):
        for model in ("firefly", "ant"):
            for field in ("static", "dynamic"):
                scs.append(load(name).replace(movementModel=model, field=field, maxTicks=2500))
    scs.append(load("wall").replace(behaviour="aggregate", maxTicks=1500))
    # a crowd that yields to the carried object, in both fields
    scs += [validate({"agents": 120, "crowd": "yield", "field": f, "maxTicks": 1500})
            for f in ("static", "dynamic")]
    return scs, [1 + j % 2 for j in range(len(scs))]


def wrap_scenarios():
    """wrap = true: both movement models, both activations, the
    NetLogo Signal and tie rules, and a yielding crowd with the dynamic field
    in a small arena, so robots and fields cross the edges often; one run of
    each, the seeds alternating."""
    scs = [validate({"wrap": True, "movementModel": model, "activation": act,
                     "maxTicks": 1200})
           for model in ("firefly", "ant") for act in ("sync", "netlogo")]
    scs.append(validate({"wrap": True, "signalMode": "netlogo", "uphillTies": "netlogo",
                         "leaderField": "netlogo", "maxTicks": 1200}))
    scs.append(validate({"wrap": True, "worldSize": 12, "agents": 30, "objectX": 0,
                         "objectY": 0, "homeX": -9, "homeY": -9, "sigRadius": 7,
                         "field": "dynamic", "crowd": "yield", "maxTicks": 1200}))
    return scs, [1 + j % 2 for j in range(len(scs))]


def count_pushes(monkeypatch) -> list[int]:
    """Record every push along the crowd (kernel._chain, crowd "yield") the
    Python kernel makes from now on: the free cell it ended at, -1 none.
    The compiled engine reads the real kernel: patch only around Python runs."""
    from sim_backend import kernel
    pushes: list[int] = []
    chain = kernel._chain

    def counted(*a):
        k = chain(*a)
        pushes.append(k)
        return k
    monkeypatch.setattr(kernel, "_chain", counted)
    return pushes


def count_crowding(monkeypatch) -> dict[str, int]:
    """Count, from now on in the Python kernel, the robots that stepped
    aside for the carried group ("aside", crowd "yield", kernel._aside) and
    the steps of the group a robot blocked ("blocked", crowd "block",
    kernel._blocked on a free patch a non-holder stands on). Patch only
    around Python runs, as count_pushes."""
    from sim_backend import kernel
    seen = {"aside": 0, "blocked": 0}
    aside, blocked = kernel._aside, kernel._blocked

    def counted_aside(*a):
        k = aside(*a)
        seen["aside"] += k >= 0
        return k

    def counted_blocked(g, rb, run, r, px, py):
        b = blocked(g, rb, run, r, px, py)
        if b and kernel.inside(run.w[r], px, py):
            k = kernel.cell(run.w[r], run.n[r], px, py)
            if g.occ[run.base[r] + k] > 0 and not kernel._holder_at(g, rb, run, r, k) and \
                    (g.obj[run.base[r] + k] == kernel.FREE or kernel._carried(g, run, r, k)):
                seen["blocked"] += 1
        return b
    monkeypatch.setattr(kernel, "_aside", counted_aside)
    monkeypatch.setattr(kernel, "_blocked", counted_blocked)
    return seen
