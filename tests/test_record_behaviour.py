"""A recording names its behaviour portably: an installed one by name, a
folder by its path relative to the recording (never an absolute path);
`replay --behaviour DIR` points at a folder that moved."""

import json
import shutil

from bridge.cli import main

RUN = ["--seed", "2", "--set", "maxTicks=200", "--link", "can"]


def sidecar(f):
    return json.loads(f.with_name(f.name + ".json").read_text())


def test_an_installed_behaviour_is_recorded_by_name(tmp_path, capsys):
    f = tmp_path / "agg.blf"
    assert main(["run", *RUN, "--behaviour", "aggregate", "--record", str(f), "--json"]) in (0, 1)
    meta = sidecar(f)
    assert meta["behaviour"] == meta["scenario"]["behaviour"] == "aggregate"
    assert meta["behaviour_name"] == "aggregate"


def test_a_folder_is_recorded_relative_and_replays_after_a_move(tmp_path, capsys, monkeypatch):
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    assert main(["behaviour", "new", "mine", "--into", "."]) == 0
    (work / "runs").mkdir()
    f = work / "runs" / "r.blf"
    assert main(["run", *RUN, "--behaviour", "./mine", "--record", "runs/r.blf",
                 "--json"]) in (0, 1)
    meta = sidecar(f)
    assert meta["behaviour"] == meta["scenario"]["behaviour"] == "../mine"
    assert meta["behaviour_name"] == "mine"
    assert str(tmp_path) not in f.with_name("r.blf.json").read_text()
    capsys.readouterr()

    # the project moved as a whole (recording and behaviour together): replays,
    # once the user trusts the folder the sidecar names (a data file names,
    # never imports: docs/security.md)
    moved = tmp_path / "elsewhere"
    shutil.move(str(work), str(moved))
    monkeypatch.chdir(tmp_path)
    assert main(["replay", str(moved / "runs" / "r.blf")]) == 2
    assert "names the behaviour folder" in capsys.readouterr().err
    assert main(["replay", str(moved / "runs" / "r.blf"), "--trust-behaviour",
                 str(moved / "mine"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["divergences"] == 0

    # only the recording moved: named in one line, then found with --behaviour
    lone = tmp_path / "lone.blf"
    shutil.copy(moved / "runs" / "r.blf", lone)
    shutil.copy(moved / "runs" / "r.blf.json", tmp_path / "lone.blf.json")
    assert main(["replay", str(lone)]) == 2
    err = capsys.readouterr().err.strip()
    assert "'../mine' ('mine')" in err and "--behaviour DIR" in err and "\n" not in err
    assert main(["replay", str(lone), "--behaviour", str(moved / "mine"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["divergences"] == 0
    # another behaviour's folder is refused, naming both
    assert main(["replay", str(lone), "--behaviour", str(moved / "mine" / "..")]) == 2
    assert main(["behaviour", "new", "other", "--into", str(tmp_path)]) == 0
    capsys.readouterr()
    assert main(["replay", str(lone), "--behaviour", str(tmp_path / "other")]) == 2
    err = capsys.readouterr().err.strip()
    assert "is behaviour 'other'" in err and "recorded with 'mine'" in err


def test_the_sidecar_describes_the_run_not_the_scenario_s_own_behaviour(tmp_path, capsys):
    """The default scenario's description speaks of the thesis's run; another
    behaviour's recording gets one of its own (robots, behaviour), the
    thesis's keeps the scenario's."""
    from sim_backend import scenario
    own = scenario.load("default").description
    assert own
    agg, thesis = tmp_path / "agg.blf", tmp_path / "thesis.blf"
    assert main(["run", *RUN, "--behaviour", "aggregate", "--robots", "7", "--record",
                 str(agg), "--json"]) in (0, 1)
    assert main(["run", *RUN, "--record", str(thesis), "--json"]) in (0, 1)
    assert sidecar(agg)["scenario"]["description"] == "7 robots, behaviour aggregate"
    assert sidecar(thesis)["scenario"]["description"] == own
    # the Python API's replace() leaves the old behaviour's description behind too
    assert scenario.load("default").replace(behaviour="aggregate").description == ""
    assert scenario.load("default").replace(agents=5).description == own
