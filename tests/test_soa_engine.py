"""The struct-of-arrays batch engine (sim_backend/batch/soa.py) runs the
behaviour's own source through the transform (sim_backend/batch/transform.py)
and equals the reference engine bit for bit: the same differential harness
as the jitclass batch engine, the same single-source test on a mutated copy,
named errors for constructs outside the transform, and a warm start from the
on-disk cache in a second process.
"""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from firmware_logic import registry
from sim_backend import objects
from sim_backend.batch.compiler import CompileError
from sim_backend.batch.soa import SoaEngine
from sim_backend.scenario import validate
from tests.harness import arena_scenarios, assert_same, mixed_scenarios, reference

ROOT = Path(__file__).resolve().parent.parent
THESIS_DIR = Path(registry.load("thesis").folder)


@pytest.mark.parametrize("behaviour", sorted(registry.names()))
@pytest.mark.parametrize("model", ["firefly", "ant"])
@pytest.mark.parametrize("activation", ["sync", "netlogo"])
def test_every_behaviour_model_and_object_identical(behaviour, model, activation):
    scs, seeds = [], []
    for obj in sorted(objects.SHAPES):
        sc = validate({"behaviour": behaviour, "movementModel": model, "object": obj,
                       "maxTicks": 3000, "activation": activation})
        for seed in (1, 2):
            scs.append(sc)
            seeds.append(seed)
    got = assert_same(scs, seeds, engine=SoaEngine)
    assert any(r.delivered for r in got), "no run reached its goal: a weak comparison"


@pytest.mark.parametrize("extra", [
    {"movementModel": "levy"}, {"movementModel": "moth"},
    {"movementModel": "frog", "frogPause": 1, "frogJump": 9},
    {"movementModel": "ant", "antBlocked": "turn"},
    {"breeds": [{"count": 6, "movementModel": "levy", "rPower": 2.0},
                {"count": 8, "movementModel": "ant", "antBlocked": "turn"},
                {"count": 6, "movementModel": "moth", "mothNoise": 60}]},
], ids=lambda d: ",".join(f"{k}={v}" for k, v in d.items()))
def test_the_other_movement_models_identical(extra):
    scs, seeds = [], []
    for obj in ("bar", "L"):
        for seed in (1, 2):
            scs.append(validate({**extra, "object": obj, "maxTicks": 1500}))
            seeds.append(seed)
    got = assert_same(scs, seeds, engine=SoaEngine)
    assert any(r.coordinator.converged_tick >= 0 for r in got), "nothing converged"


def test_many_seeds_and_mixed_parameters_in_one_batch():
    scs, seeds = mixed_scenarios()
    got = assert_same(scs, seeds, engine=SoaEngine)
    assert len({r.ticks for r in got}) > 5


def test_obstacles_several_objects_and_the_dynamic_field_identical():
    scs, seeds = arena_scenarios()
    got = assert_same(scs, seeds, engine=SoaEngine)
    assert sum(r.delivered for r in got) >= len(got) // 2, "few deliveries: a weak comparison"


def test_faults_identical():
    sc = validate({"maxTicks": 1500, "deathRate": 0.2, "deadlockRate": 0.1,
                   "ignoreFieldRate": 0.1, "ignoreHostRate": 0.1, "randomRate": 0.1,
                   "probeMiss": 0.1, "probeGhost": 0.02, "fieldNoise": 2})
    assert_same([sc] * 3, [1, 2, 3], engine=SoaEngine)


def test_until_converged_stops_where_the_reference_stops():
    sc = validate({"movementModel": "ant"})
    got = assert_same([sc] * 3, [5, 6, 7], until="converged", engine=SoaEngine)
    assert all(r.coordinator.converged_tick == r.ticks for r in got if r.ticks < sc.maxTicks)


def test_final_robots_are_the_reference_robots():
    """At a run's end the arrays are written back into the CPython robots."""
    sc = validate({"maxTicks": 600})
    got = assert_same([sc], [4], engine=SoaEngine)[0]
    ref = reference(sc, 4)
    for a, b in zip(ref.robots, got.robots):
        va, vb = dict(vars(a)), dict(vars(b))
        assert vars(va.pop("rng")) == vars(vb.pop("rng"))
        assert va == vb


def test_one_rule_changed_in_the_source_changes_both_engines_identically(tmp_path):
    """Single source: the firefly's random heading drawn from 0..179 in a copy."""
    mutant = tmp_path / "thesis_half_turns"
    shutil.copytree(THESIS_DIR, mutant, ignore=shutil.ignore_patterns("__pycache__"))
    robot = mutant / "robot.py"
    src = robot.read_text()
    rule = ("        if m == FIREFLY:\n"
            "            self.heading = self.rng.below(360)\n"
            "        elif m == LEVY:")
    assert src.count(rule) == 1, "the rule this test mutates has moved; update the test"
    robot.write_text(src.replace(rule, rule.replace("below(360)", "below(180)")))
    original = validate({"maxTicks": 400})
    changed = validate({"behaviour": str(mutant), "maxTicks": 400})
    got = assert_same([changed] * 2, [1, 2], engine=SoaEngine)
    for seed, b in zip([1, 2], got):
        before = reference(original, seed)
        assert b.trajectories != before.trajectories[:len(b.trajectories)], seed


def _mutated_aggregate(tmp_path, name, anchor, insert):
    agg = registry.load("aggregate")
    copy = tmp_path / name
    shutil.copytree(agg.folder, copy, ignore=shutil.ignore_patterns("__pycache__"))
    robot = copy / "robot.py"
    src = robot.read_text()
    assert src.count(anchor) == 1, "the anchor of this test has moved; update the test"
    robot.write_text(src.replace(anchor, anchor + insert))
    return validate({"behaviour": str(copy)}), robot


def test_an_attribute_outside_the_subset_is_named(tmp_path):
    sc, _ = _mutated_aggregate(tmp_path, "aggregate_float",
                               "        self.rxbuf = [0, 0, 0, 0, 0, 0]\n",
                               "        self.gain = 0.5\n")
    with pytest.raises(CompileError, match=r"Robot\.gain: a float"):
        SoaEngine([(sc, 1)])


@pytest.mark.parametrize("construct,code,named", [
    ("try", "        try:\n            self.ticks += 0\n        except ValueError:\n"
            "            pass\n", "a Try statement"),
    ("list", "        self.ticks += len([1, 2])\n", "a List expression"),
    ("new object", "        Robot(1, 1, 0, 0, 0, 0)\n", "constructing a Robot"),
    ("unknown attribute", "        self.nowhere += 1\n", "Robot.nowhere"),
])
def test_a_construct_outside_the_transform_is_named_with_its_line(tmp_path, construct, code,
                                                                   named):
    anchor = "    def step(self, hal):\n"
    sc, robot = _mutated_aggregate(tmp_path, "aggregate_" + construct.replace(" ", "_"),
                                   anchor, code)
    line = robot.read_text().split("\n").index(code.split("\n")[0]) + 1
    with pytest.raises(CompileError, match=f"robot.py:{line}: {named}"):
        SoaEngine([(sc, 1)])


WARM = """
import json, sys
from sim_backend.batch.soa import SoaEngine
from sim_backend.scenario import validate
e = SoaEngine([(validate({"maxTicks": 50}), 1)])
e.step()
s = e._tick_fn.stats
print(json.dumps({"hits": sum(s.cache_hits.values()), "misses": sum(s.cache_misses.values()),
                  "xs": e.rb[0].tolist(), "dir": str(e.compiled.path.parent)}))
"""


def test_a_second_process_loads_the_compiled_step_from_the_disk_cache(tmp_path):
    env = {**os.environ, "TOUCHSWARM_CACHE": str(tmp_path), "PYTHONPATH": str(ROOT)}
    runs = []
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", WARM], env=env, capture_output=True,
                             text=True, check=True, cwd=ROOT)
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    cold, warm = runs
    assert cold["misses"] >= 1 and cold["hits"] == 0
    assert warm["hits"] >= 1 and warm["misses"] == 0
    assert warm["xs"] == cold["xs"]
    assert Path(cold["dir"]).parent == tmp_path / "soa"
    assert list(Path(cold["dir"]).glob("__pycache__/*.nbi"))
