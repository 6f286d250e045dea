"""Ants that stay ants (antBlocked) and the Levy, moth and
frog movement models of the thesis behaviour (docs/movement-models.md).

Each model is deterministic per seed, differs from the others, runs over
virtual CAN like in process, and has its rule checked on a hand-driven HAL;
out-of-range keys get one-line errors. Batch == reference for every model is
in tests/test_batch_engine.py; MicroPython == CPython in `firmware check`.
"""

import pytest

from bridge.links.canlink import CanLink
from firmware_logic.behaviours.thesis import spec
from firmware_logic.behaviours.thesis.robot import FIELD, LEVY_KMAX, MOTH_SPIRAL, Robot
from firmware_logic.hal import WALL
from sim_backend.engine import Engine, run
from sim_backend.errors import ScenarioError
from sim_backend import params
from sim_backend.scenario import validate
from tests.fakehal import FakeHal

NEW = ("levy", "moth", "frog")


def test_the_scenario_models_are_the_specs():
    model = {p.name: p for p in params.declared("thesis")}["movementModel"]
    assert model.codes == spec.MODELS and model.choices == tuple(n for _, n in spec.MODELS)
    assert set(NEW) <= set(model.choices)
    assert validate({"movementModel": 3}).movementModel == "levy"


@pytest.mark.parametrize("raw, needle", [
    ({"levyMu": 1.0}, "levyMu: 1.0 is outside the allowed range 1.1..3.0"),
    ({"levyMu": 3.5}, "levyMu"),
    ({"mothNoise": -1}, "mothNoise"),
    ({"mothNoise": 181}, "mothNoise"),
    ({"frogPause": 0}, "frogPause"),
    ({"frogJump": 31}, "frogJump"),
    ({"frogJump": 2.5}, "frogJump"),
    ({"antBlocked": "spin"}, "antBlocked: expected one of 'random', 'turn', got 'spin'"),
    ({"movementModel": "bee"}, "movementModel: expected one of 'firefly' (1)"),
    ({"movementModel": 6}, "movementModel"),
    ({"movementModel": "moth", "behaviour": "aggregate"},
     "movementModel: expected one of 'firefly' (1), 'ant' (2), got 'moth'"),
])
def test_new_keys_out_of_range_get_one_line_errors(raw, needle):
    with pytest.raises(ScenarioError) as err:
        validate(raw)
    assert needle in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize("model", NEW)
def test_each_model_is_deterministic_per_seed_and_its_own(model):
    sc = validate({"movementModel": model, "maxTicks": 400})
    a = Engine(sc, 5, record_trajectories=True).run()
    b = Engine(sc, 5, record_trajectories=True).run()
    assert a.trajectories == b.trajectories and a.summary() == b.summary()
    other = Engine(validate({"maxTicks": 400}), 5, record_trajectories=True).run()
    assert a.trajectories[:50] != other.trajectories[:50]
    c = Engine(sc, 6, record_trajectories=True).run()
    assert a.trajectories[:50] != c.trajectories[:50]


@pytest.mark.parametrize("model", NEW)
def test_each_model_finds_and_converges(model):
    """Over a few seeds each model touches the object and gathers its weight."""
    sc = validate({"movementModel": model, "maxTicks": 3000})
    conv = [run(sc, s).coordinator.converged_tick for s in (1, 2, 3)]
    assert all(t > 0 for t in conv), conv


@pytest.mark.parametrize("model", ("levy", "frog"))
def test_a_model_runs_over_virtual_can_as_in_process(model):
    sc = validate({"movementModel": model, "maxTicks": 600})
    link = CanLink(list(range(1, sc.agents + 1)))
    try:
        over_can = Engine(sc, 3, link=link).run().summary()
    finally:
        link.close()
    assert over_can == run(sc, 3).summary()
    assert over_can["found_tick"] is not None


# -- the rules on a hand-driven HAL ------------------------------------------------

def robot(model, **kw):
    args = dict(ant_turn=0, levy_q=500, moth_noise=30, frog_pause=4, frog_jump=4)
    args.update(kw)
    return Robot(3, 11, model, 45, 2, 100, 0, args["ant_turn"], args["levy_q"],
                 args["moth_noise"], args["frog_pause"], args["frog_jump"])


@pytest.mark.parametrize("ant_turn, within", [(1, True), (0, False)])
def test_a_blocked_ant_turns_within_its_span_only_with_turn(ant_turn, within):
    """antBlocked=turn: every blocked step stays within +-span of the heading
    (an ant stays an ant); random (the thesis): some leave it."""
    r = robot(spec.ANT, ant_turn=ant_turn)
    hal = FakeHal()
    hal.probe_default = WALL
    inside = []
    for _ in range(200):
        before = r.heading
        r._head_carefully(hal)
        d = (r.heading - before) % 360
        inside.append(min(d, 360 - d) <= 45)
    assert all(inside) is within


def test_levy_flight_lengths_follow_the_truncated_power_law():
    """P(flight >= 2**k) = q**k: halving at mu = 2, thinner tails for larger mu."""
    def lengths(q):
        r = robot(spec.LEVY, levy_q=q)
        out = []
        for _ in range(4000):
            r._new_flight()
            out.append(r.flight)
        return out
    two = lengths(500)
    assert min(two) == 1 and max(two) <= 2 ** (LEVY_KMAX + 1) - 1
    share = sum(v >= 2 for v in two) / len(two)
    assert 0.45 < share < 0.55
    share4 = sum(v >= 4 for v in two) / len(two)
    assert 0.2 < share4 < 0.3
    steep = lengths(round(1000 * 2 ** (1 - 3.0)))          # mu = 3
    assert sum(steep) < sum(two)
    from sim_backend import registry
    sc = validate({"levyMu": 3.0, "movementModel": "levy"})
    assert registry.load("thesis").robot_args(1, 1, sc)[8] == 250   # the FSM's levy_q


def test_a_levy_walker_keeps_its_heading_for_the_flight():
    r = robot(spec.LEVY)
    hal = FakeHal()
    r.flight = 5
    r.heading = 90
    for _ in range(5):
        r._random_head(hal)
    assert r.heading == 90 and r.flight == 0
    r._random_head(hal)                    # a new flight, a new heading
    assert r.flight >= 0


def test_the_moth_steers_uphill_with_noise_and_circles_at_the_peak():
    r = robot(spec.MOTH, moth_noise=20)
    hal = FakeHal()
    hal.up = 90
    seen = set()
    for _ in range(300):
        r._moth_steer(hal)
        seen.add(r.heading)
    assert min(seen) == 70 and max(seen) == 110
    hal.up = -1
    r.heading = 10
    r._moth_steer(hal)
    assert r.heading == 10 + MOTH_SPIRAL
    r.state = FIELD
    r._random_head(hal)                     # in a field every move steers
    assert r.heading == 10 + 2 * MOTH_SPIRAL


def test_the_frog_sits_then_jumps_several_patches():
    r = robot(spec.FROG, frog_pause=3, frog_jump=5)
    hal = FakeHal()
    moves = []
    for _ in range(40):
        n = len(hal.log)
        r._random_head(hal)
        moves.append(any(c[0] == "probe" for c in hal.log[n:]))
    # after the first jump: runs of 5 moving ticks separated by 2 sitting ticks
    text = "".join("J" if m else "s" for m in moves)
    assert "sJJJJJss" in text and "JJJJJJ" not in text, text


# -- several breeds ------------------------------------------------

BREEDS = [{"name": "fireflies", "count": 6, "movementModel": "firefly"},
          {"name": "ants", "count": 8, "movementModel": "ant", "rPower": 2.0,
           "antBlocked": "turn"},
          {"name": "frogs", "count": 6, "movementModel": "frog", "frogJump": 6}]


def test_breeds_load_from_toml_and_number_nodes_breed_by_breed(tmp_path):
    f = tmp_path / "mix.toml"
    f.write_text("".join(
        "[[breeds]]\n" + "".join(f"{k} = {v!r}\n".replace("'", '"') for k, v in b.items())
        for b in BREEDS))
    from sim_backend.scenario import load
    sc = load(f)
    assert sc.agents == 20
    assert [sc.breed_name(n) for n in (1, 6, 7, 14, 15, 20)] == \
        ["fireflies", "fireflies", "ants", "ants", "frogs", "frogs"]
    assert sc.for_node(7).rPower == 2.0 and sc.for_node(7).antBlocked == "turn"
    assert sc.for_node(20).frogJump == 6 and sc.for_node(1).frogJump == 4
    e = Engine(sc, 4)
    assert [r.model for r in e.robots] == [1] * 6 + [2] * 8 + [5] * 6
    assert [r.power for r in e.robots] == [100] * 6 + [200] * 8 + [100] * 6
    assert e.robots[8].ant_turn == 1 and e.robots[0].ant_turn == 0


def test_the_host_and_the_records_know_each_robots_breed():
    sc = validate({"breeds": BREEDS, "maxTicks": 3000})
    r = Engine(sc, 4).run()
    # the host learnt model and power per node from each HELLO
    assert r.coordinator.nodes[7] == (2, 200) and r.coordinator.nodes[20] == (5, 100)
    s = r.summary()
    assert len(s["touch_breeds"]) == len(s["touches"]) > 0
    assert s["touch_breeds"] == [sc.breed_name(t.node) for t in r.coordinator.touches]
    assert "touch_breeds" not in run(validate({"maxTicks": 50}), 4).summary()


@pytest.mark.parametrize("raw, needle", [
    ({"breeds": [{"movementModel": "ant"}]}, "breeds #1: expected a table with count"),
    ({"breeds": [{"count": 0}]}, "breeds #1: count: expected int in 1..20000"),
    ({"breeds": [{"count": 3, "quorum": 5}]}, "breeds #1: unknown key 'quorum'"),
    ({"breeds": [{"count": 3, "levyMu": 9}]}, "levyMu: 9 is outside"),
    ({"breeds": {"count": 3}}, "breeds: expected a list of tables"),
    ({"breeds": [{"count": 3}, {"count": 4}], "agents": 8}, "agents: 8 differs"),
    ({"breeds": [{"count": 4, "rPower": 0.5}]}, "objectWeight: weight 5 is more than all 4 robots can hold together"),
    ({"behaviour": "aggregate", "breeds": [{"count": 4, "movementModel": "levy"}]},
     "movementModel: expected one of 'firefly' (1), 'ant' (2), got 'levy'"),
    ({"behaviour": "aggregate", "breeds": [{"count": 8, "antBlocked": "turn"}]}, "antBlocked"),
])
def test_bad_breeds_get_one_line_errors(raw, needle):
    with pytest.raises(ScenarioError) as err:
        validate(raw)
    assert needle in str(err.value) and "\n" not in str(err.value)


def test_breeds_run_over_virtual_can_as_in_process():
    sc = validate({"breeds": BREEDS, "maxTicks": 500})
    link = CanLink(list(range(1, sc.agents + 1)))
    try:
        over_can = Engine(sc, 2, link=link).run().summary()
    finally:
        link.close()
    assert over_can == run(sc, 2).summary()


def test_the_breed_preset_varies_the_ant_share():
    from sim_backend import studies
    pts = studies.get("thesis", "breeds").points
    shares = []
    for p in pts:
        sc = validate(p.as_dict())
        shares.append(sum(1 for n in range(1, sc.agents + 1)
                          if sc.for_node(n).movementModel == "ant"))
        assert sc.agents == 20
    assert shares == [0, 5, 10, 15, 20]
