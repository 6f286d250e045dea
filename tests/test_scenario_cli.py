"""Scenarios and the `touchswarm run` command line, bad input included."""

import json
import subprocess
import sys

import pytest

from sim_backend import scenario
from sim_backend.errors import ScenarioError

CLI = [sys.executable, "-m", "bridge.cli"]


def cli(*args, **kw):
    return subprocess.run(CLI + list(args), capture_output=True, text=True, timeout=120, **kw)


def test_builtin_scenarios_load_with_thesis_names():
    names = scenario.builtin_names()
    assert {"default", "ant", "L", "cross", "X", "plus", "T", "square"} <= set(names)
    sc = scenario.load("ant")
    assert sc.movementModel == "ant" and sc.agents == 20


@pytest.mark.parametrize("raw, needle", [
    ({"colour": 1}, "unknown key 'colour'"),
    ({"fieldDefiance": -1}, "fieldDefiance: -1 is outside the allowed range 0..50"),
    ({"agents": 2.5}, "agents: expected int"),
    ({"movementModel": "bee"}, "movementModel: expected one of 'firefly' (1), 'ant' (2)"),
    ({"object": 9}, "object: expected 1-4"),
    ({"objectX": 12}, "does not fit the arena"),
    ({"objectX": 3}, "objectX, objectY: set both or neither"),
    ({"objectWeight": 30.0}, "objectWeight: weight 30 is more than all 20 robots"),
    ({"objectWeight": 19.0, "agents": 24, "object": "square"}, "reachable segments"),
])
def test_bad_scenarios_name_the_key_and_the_allowed_values(raw, needle):
    with pytest.raises(ScenarioError) as err:
        scenario.validate(raw)
    assert needle in str(err.value)


def test_thesis_object_numbers_are_accepted():
    assert scenario.validate({"object": 4}).object == "X"
    assert scenario.validate({"movementModel": 2}).movementModel == "ant"


@pytest.mark.parametrize("args, needle", [
    (["--set", "sigRadius=99"], "sigRadius: 99 is outside the allowed range 0..30"),
    (["--scenario", "nosuch"], "neither a built-in"),
    (["--set", "oops"], "expected KEY=VALUE"),
    (["--robots", "0"], "agents: 0 is outside"),
])
def test_cli_bad_input_is_one_line_exit_2_no_traceback(args, needle):
    p = cli("run", *args)
    assert p.returncode == 2
    assert needle in p.stderr
    assert "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) == 1


def test_bad_scenario_file_is_reported(tmp_path):
    f = tmp_path / "bad.toml"
    f.write_text('agents = 20\nrPower = "strong"\n')
    p = cli("run", "--scenario", str(f))
    assert p.returncode == 2 and "rPower: expected float" in p.stderr
    f.write_text("agents = = 3\n")
    p = cli("run", "--scenario", str(f))
    assert p.returncode == 2 and "not valid TOML" in p.stderr


def test_run_json_has_the_promised_keys(tmp_path):
    p = cli("run", "--json", "--seed", "4", "--robots", "12")
    assert p.returncode == 0, p.stderr
    out = json.loads(p.stdout)
    for key in ("seed", "robots", "found_tick", "converged_tick", "home_tick", "touches",
                "shape_iou", "leader", "delivered"):
        assert key in out
    assert out["seed"] == 4 and out["robots"] == 12 and out["delivered"] is True
    assert out["found_tick"] <= out["converged_tick"] < out["home_tick"]
    assert all(len(t) == 2 for t in out["touches"])


def test_same_seed_same_output_byte_for_byte(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    pa = cli("run", "--seed", "9", "--out", str(a))
    pb = cli("run", "--seed", "9", "--out", str(b))
    assert pa.stdout.replace(str(a), "OUT") == pb.stdout.replace(str(b), "OUT")
    assert pa.returncode == 0
    names = sorted(p.name for p in a.iterdir())
    assert names == ["ct.csv", "indstats.csv", "shape.csv", "summary.json", "tt.csv", "world.png"]
    for n in names:
        assert (a / n).read_bytes() == (b / n).read_bytes(), n
    c = tmp_path / "c"
    cli("run", "--seed", "10", "--out", str(c))
    assert (c / "indstats.csv").read_bytes() != (a / "indstats.csv").read_bytes()


def test_scenario_file_round_trip(tmp_path):
    f = tmp_path / "mine.toml"
    f.write_text('name = "mine"\nagents = 15\nmovementModel = "ant"\nobject = "L"\n'
                 'fieldDefiance = 1\n')
    p = cli("run", "--scenario", str(f), "--json")
    out = json.loads(p.stdout)
    assert out["scenario"] == "mine" and out["robots"] == 15 and out["object"] == "L"


def test_help_answers_questions():
    p = cli("run", "--help")
    assert "--scenario" in p.stdout and "--set" in p.stdout and "--json" in p.stdout


def test_real_links_refuse_more_robots_than_node_ids():
    p = cli("run", "--link", "can", "--robots", "200", "--set", "worldSize=60")
    assert p.returncode == 2 and "allowed 1..127" in p.stderr
    p = cli("run", "--robots", "200", "--set", "worldSize=60", "--json")
    assert p.returncode == 0 and json.loads(p.stdout)["robots"] == 200


@pytest.mark.parametrize("args, needle", [
    (["deploy", "--port", "/dev/ttyACM97"], "--port /dev/ttyACM97: no such device"),
    (["deploy", "--port", "/dev/null", "--behaviour", "nope"], "--behaviour: behaviour 'nope'"),
    (["run", "--set", "behaviour=nope"], "behaviour 'nope': not an installed behaviour"),
    (["sweep", "--grid", "sigRadius=3", "--engine", "soa", "--set", "behaviour=nope"],
     "behaviour 'nope'"),
])
def test_more_bad_commands_are_one_line_exit_2(args, needle):
    p = cli(*args)
    assert p.returncode == 2, p.stderr
    assert needle in p.stderr
    assert "Traceback" not in p.stderr and len(p.stderr.strip().splitlines()) == 1
