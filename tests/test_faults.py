"""Faults injected on the body side (sim_backend/faults.py).

Faults off is bit-identical to a run that never heard of them; every fault
is seeded (same seed, same run) and equal in the reference and batch
engines; each fault does what it says; out-of-range keys get one-line errors.
"""

import pytest

from firmware_logic.behaviours.thesis.spec import HOLD
from sim_backend import faults
from sim_backend.engine import Engine
from sim_backend.errors import ScenarioError
from sim_backend.scenario import RANGES, Scenario, validate
from tests.harness import assert_same

OFF = {"deathRate": 0.0, "deadlockRate": 0.0, "ignoreFieldRate": 0.0, "ignoreHostRate": 0.0,
       "randomRate": 0.0, "probeMiss": 0.0, "probeGhost": 0.0, "fieldNoise": 0}
GOAL = {"deathRate": 0.25, "ignoreFieldRate": 0.1, "randomRate": 0.1}


def traced(raw, seed):
    return Engine(validate(raw), seed, record_trajectories=True).run()


def test_faults_explicitly_off_are_bit_identical_to_absent():
    for seed in (1, 4):
        a = traced({"movementModel": "ant", "maxTicks": 1500}, seed)
        b = traced({**OFF, "movementModel": "ant", "maxTicks": 1500}, seed)
        assert a.summary() == b.summary()
        assert a.trajectories == b.trajectories and a.states == b.states
    assert not faults.active(validate(OFF))


@pytest.mark.parametrize("key", sorted(k for k in OFF))
def test_every_fault_key_out_of_range_is_one_line(key):
    kind, lo, hi = RANGES[key]
    for bad in (lo - 1, hi + 1, "x"):
        with pytest.raises(ScenarioError) as err:
            validate({key: bad})
        assert key in str(err.value) and "\n" not in str(err.value)
    assert getattr(Scenario(), key) == 0


def test_disjoint_shares_above_one_are_refused():
    with pytest.raises(ScenarioError, match="exceeds 1"):
        validate({"deathRate": 0.6, "randomRate": 0.5})


def test_the_plan_is_seeded_disjoint_and_sized():
    sc = validate({**GOAL, "agents": 20, "deadlockRate": 0.5})
    die, s0, s1, flags = faults.plan(sc, 7)
    assert faults.plan(sc, 7) == (die, s0, s1, flags)
    assert faults.plan(sc, 8) != (die, s0, s1, flags)
    dead = [i for i, d in enumerate(die) if d != faults.NEVER]
    assert len(dead) == 5 and all(1 <= die[i] <= sc.faultWindow for i in dead)
    assert sum(1 for f in flags if f & faults.IGNORE_FIELD) == 2
    assert sum(1 for f in flags if f & faults.RANDOM) == 2
    assert not any(flags[i] for i in dead)
    assert sum(1 for t in s0 if t != faults.NEVER) == 10
    assert all(b - a == sc.deadlockTicks for a, b in zip(s0, s1) if a != faults.NEVER)


@pytest.mark.parametrize("raw", [
    GOAL,
    {"probeMiss": 0.3, "probeGhost": 0.05, "fieldNoise": 3},
    {"deadlockRate": 0.5, "deadlockTicks": 60, "faultWindow": 200},
    {"ignoreHostRate": 0.2, "maxTicks": 700},
    {**GOAL, "movementModel": "levy"},
], ids=["goal", "sensors", "deadlock", "ignore-host", "goal-levy"])
def test_faults_are_equal_in_both_engines(raw):
    scs = [validate({"maxTicks": 2500, **raw})] * 2
    got = assert_same(scs, [1, 2])
    assert any(r.coordinator.converged_tick >= 0 for r in got)


def test_a_dead_robot_stops_where_it_died_and_falls_silent():
    # crowd "block": with "yield" (the default) the world also moves a robot,
    # dead or alive, that stands in the carried object's way (it is pushed
    # aside, docs/extensions.md); here no robot may move once dead
    sc = validate({"deathRate": 0.5, "faultWindow": 50, "maxTicks": 400, "crowd": "block"})
    die, _, _, _ = faults.plan(sc, 3)
    e = Engine(sc, 3, record_trajectories=True)
    r = e.run()
    moved_after = []
    for i, d in enumerate(die):
        if d == faults.NEVER or d >= r.ticks:
            continue
        xs = [r.trajectories[t][0][i] for t in range(d - 1, r.ticks)]
        ys = [r.trajectories[t][1][i] for t in range(d - 1, r.ticks)]
        moved_after.append(len(set(zip(xs, ys))) > 1)
    assert moved_after and not any(moved_after)
    assert all(r.world.held[i] < 0 for i, d in enumerate(die) if d < r.ticks)


def test_a_dying_holder_lets_go_so_the_others_deliver():
    """The host's rule (docs/extensions.md): a holder that dies goes limp, its
    segment is free again and the carried group moves without it; the run
    with a holder dead during the transport still delivers."""
    base = {"maxTicks": 4000}
    healthy = traced(base, 2)
    assert healthy.delivered
    conv = healthy.coordinator.converged_tick
    holder = next(i for i, st in enumerate(healthy.states[conv - 1]) if st == HOLD)
    # kill exactly that holder a few ticks after convergence, through the plan
    orig = faults.plan

    def plan(sc, seed):
        die, s0, s1, flags = orig(sc, seed)
        die = [faults.NEVER] * len(die)
        die[holder] = conv + 3
        return die, s0, s1, flags
    faults.plan = plan
    try:
        sc = validate({**base, "faultWindow": 1, "probeMiss": 0.0001})
        hurt = Engine(sc, 2, record_trajectories=True).run()
    finally:
        faults.plan = orig
    assert hurt.world.held[holder] < 0
    assert hurt.delivered, hurt.summary()


def test_random_agents_never_claim_and_ignoring_the_field_never_climbs():
    sc = validate({"randomRate": 0.5, "ignoreFieldRate": 0.5, "maxTicks": 1500})
    _, _, _, flags = faults.plan(sc, 5)
    r = traced({"randomRate": 0.5, "ignoreFieldRate": 0.5, "maxTicks": 1500}, 5)
    claimed = {t.node for t in r.coordinator.touches}
    rnd = {i + 1 for i, f in enumerate(flags) if f & faults.RANDOM}
    assert rnd and not claimed & rnd
    assert claimed, "the non-complying half still touches the object"


def test_probe_misses_slow_the_first_touch_on_average():
    seeds = range(1, 9)
    clean = [traced({"maxTicks": 3000}, s).coordinator.found_tick for s in seeds]
    missy = [traced({"probeMiss": 0.9, "maxTicks": 3000}, s).coordinator.found_tick
             for s in seeds]
    assert sum(missy) > sum(clean)


# -- the link's faults (the CAN fault injector, exposed as scenario keys) ---------

def test_link_faults_over_can_are_seeded_and_change_the_run():
    from bridge.links.canlink import CanLink, faults_of

    def over_can(raw, seed):
        sc = validate({"maxTicks": 1500, **raw})
        up, down = faults_of(sc, seed)
        link = CanLink(list(range(1, sc.agents + 1)), faults_up=up, faults_down=down)
        try:
            res = Engine(sc, seed, link=link).run()
            # both ways: frames up (robots -> host) and down are lost
            assert (up is None) == (link.gateway.faults is None) and \
                (down is None) == (link.faults_down is None)
            dropped = (up.dropped, down.dropped) if up else (0, 0)
            return res.summary(), dropped
        finally:
            link.close()
    lossy = {"linkLoss": 0.3, "linkReorder": 3}
    a, dropped = over_can(lossy, 3)
    b, _ = over_can(lossy, 3)
    clean, none = over_can({}, 3)
    assert a == b and min(dropped) > 0 and none == (0, 0)
    assert a["delivered"], "retransmission carries the mission through 30 % loss"
    assert (a["converged_tick"], a["home_tick"]) != (clean["converged_tick"], clean["home_tick"])
    assert faults_of(validate({}), 3) == (None, None)


def test_link_delay_holds_frames_back_and_loses_none():
    """linkDelay: every frame arrives, each 0..delay ticks late, and late
    frames overtake each other; delay 0 is the injector as it was."""
    from bridge.links.canlink import Faults
    f = Faults(7, delay=3)
    got = []
    for now in range(20):
        sent = [(now, k) for k in range(5)] if now < 10 else []
        for frame in f.apply(sent, now):
            got.append((now, frame))
    assert sorted(fr for _, fr in got) == [(t, k) for t in range(10) for k in range(5)]
    lags = [now - fr[0] for now, fr in got]
    assert min(lags) == 0 and max(lags) == 3 and f.delayed > 0 and not f.held
    assert [fr for _, fr in got] != sorted(fr for _, fr in got), "late frames are overtaken"
    plain, zero = Faults(7, loss=0.2, window=3), Faults(7, loss=0.2, window=3, delay=0)
    frames = list(range(40))
    assert plain.apply(frames) == zero.apply(frames, 0)


def test_link_delay_over_can_is_seeded_and_still_delivers():
    from bridge.links.canlink import CanLink, faults_of
    sc = validate({"maxTicks": 1500, "linkDelay": 4})

    def once():
        up, down = faults_of(sc, 5)
        link = CanLink(list(range(1, sc.agents + 1)), faults_up=up, faults_down=down)
        try:
            return Engine(sc, 5, link=link).run().summary(), (up.delayed, down.delayed)
        finally:
            link.close()
    a, late = once()
    b, _ = once()
    clean = Engine(validate({"maxTicks": 1500}), 5).run().summary()
    assert a == b and min(late) > 0 and a["delivered"]
    assert (a["converged_tick"], a["home_tick"]) != (clean["converged_tick"], clean["home_tick"])


def test_link_injectors_are_keyword_only():
    """Passed by position the injectors once landed in `channel`, and
    `run --link can` ran with the down injector as the up one."""
    from bridge.links.canlink import CanLink, Faults
    with pytest.raises(TypeError):
        CanLink([1], Faults(1), Faults(2))


@pytest.mark.parametrize("argv, needle", [
    (["run", "--set", "linkLoss=0.2"], "linkLoss: a link fault needs a link; add --link can"),
    (["run", "--set", "linkDelay=2"], "linkDelay: a link fault needs a link; add --link can"),
    (["run", "--link", "can", "--set", "linkDelay=65"], "linkDelay"),
    (["run", "--link", "can", "--set", "linkReorder=0"], "linkReorder"),
    (["sweep", "--grid", "linkDup=0.1,0.2", "--seeds", "1"], "sweeps run in process"),
    (["sweep", "--preset", "faults", "--grid", "deathRate=0.1"], "--preset faults runs its own"),
    (["sweep", "--preset", "faults", "--set", "deathRate=2"], "deathRate"),
])
def test_fault_options_refused_in_one_line(argv, needle, capsys, tmp_path):
    from bridge.cli import main
    assert main([*argv, "--out", str(tmp_path / "o")] if argv[0] == "sweep" else argv) == 2
    err = capsys.readouterr().err.strip()
    assert needle in err and "\n" not in err


def test_the_fault_preset_has_each_fault_alone_and_the_goal_mix():
    from sim_backend import studies
    from sim_backend.robustness import fault_table
    st = studies.get("thesis", "faults")
    pts = st.points
    keys = ("deathRate", "deadlockRate", "ignoreFieldRate", "ignoreHostRate", "randomRate",
            "probeMiss", "probeGhost")
    for k in keys:
        assert [p.as_dict()[k] for p in pts if p.experiment == k] == [0.0, 0.1, 0.25, 0.5]
    assert [p.as_dict()["fieldNoise"] for p in pts if p.experiment == "fieldNoise"] == \
        [0, 1, 2, 4]
    goal = [p.as_dict() for p in pts if p.experiment == "goal"]
    assert goal == [{"deathRate": 0.25, "ignoreFieldRate": 0.1, "randomRate": 0.1}]
    assert dict(st.overrides) == {"maxTicks": 3000, "faultWindow": 200, "lostAfter": 100}
    assert (st.seeds, st.until) == (40, "delivered")
    rows = [{**validate({"maxTicks": 10, **p.as_dict()}).to_dict(), "experiment": p.experiment,
             "seed": 1, "delivered": p.experiment == "goal", "home_tick": 9}
            for p in pts]
    t = fault_table(rows, "goal")
    assert t["goal"] == [(-1.0, 1, 1, 9)]
    assert t["deathRate"][0] == (0.0, 1, 0, None)
