"""A behaviour of the user's own, end to end: a third behaviour, made by the scaffold in a folder
outside the repository and edited there, with its own parameter, a state only
its own down message leads to and its own measure, passes every step from that
folder: run, sweep (both engines, identical), firmware check, CAN record +
replay, dbc, robots + host on a bus, deploy to MicroPython (the unix port
behind a pty) and a mission with the board as one robot; `behaviour check`
says so in its table.
"""

from __future__ import annotations

import csv
import json
import re
from pathlib import Path

import pytest

from bridge.cli import main
from sim_backend import registry
from tests.test_behaviour_folder import spread_behaviour


@pytest.fixture
def spread(tmp_path: Path) -> Path:
    folder = spread_behaviour(tmp_path)
    assert not folder.resolve().is_relative_to(Path(registry.__file__).parents[1])
    return folder


def test_its_parameter_and_measure_reach_run_and_sweep(spread: Path, tmp_path: Path,
                                                       capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--behaviour", str(spread), "--set", "fleeTicks=9", "--set",
                 "maxTicks=400", "--json"]) == 0
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert s["fleeTicks"] == 9 and s["nudges"] >= 1, s
    assert main(["run", "--behaviour", str(spread), "--set", "fleeTicks=99"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "fleeTicks" in err and "1..50" in err
    out = tmp_path / "sw"
    assert main(["sweep", "--set", f"behaviour={spread}", "--set", "maxTicks=200", "--grid",
                 "fleeTicks=3,9", "--seeds", "2", "--engine", "reference", "--no-plots",
                 "--out", str(out)]) == 0
    with open(out / "sweep.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert sorted(r["fleeTicks"] for r in rows) == ["3", "3", "9", "9"]
    assert all(r["nudges"] != "" for r in rows)
    capsys.readouterr()
    assert main(["scenarios", "--behaviour", str(spread)]) == 0
    assert re.search(r"fleeTicks\s+5\s+1\.\.50\s+ticks a nudged robot walks away",
                     capsys.readouterr().out)


def test_behaviour_check_passes_every_step_from_the_folder(
        spread: Path, micropython_device, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    # a new behaviour's soa compile without inlining: half the cold compile
    monkeypatch.setenv("TOUCHSWARM_SOA_INLINE", "0")
    rc = main(["behaviour", "check", str(spread), "--ticks", "300", "--port",
               micropython_device.path])
    out = capsys.readouterr().out
    rows = {m.group(1): m.group(2) for m in re.finditer(r"^  (\w+)\s+(PASS|FAIL|NOT RUN)", out,
                                                         re.M)}
    assert rows == {s: "PASS" for s in ("load", "run", "sweep", "firmware", "can", "dbc", "bus",
                                        "deploy", "mission")}, out
    assert rc == 0 and out.rstrip().endswith("behaviour check: PASS")
    flash = micropython_device.flash     # type: ignore[attr-defined]
    assert (flash / "behaviour" / "moves.mpy").exists()
    assert "ARGS = (1, 1, 1, 45, 2, 100, 5)" in (flash / "robot_config.py").read_text()


def test_the_guide_runs_as_written(micropython_device, tmp_path: Path,
                                   monkeypatch: pytest.MonkeyPatch,
                                   capsys: pytest.CaptureFixture[str]) -> None:
    """docs/writing-a-behaviour.md, sections 1 and 3: every command, as
    written, with /tmp the test's folder and /dev/ttyACM0 the pty board."""
    import shlex

    from tests.test_words import doc_commands
    monkeypatch.chdir(tmp_path)
    cmds = (doc_commands("writing-a-behaviour.md", "1. Scaffold")
            + doc_commands("writing-a-behaviour.md", "3. Run it everywhere"))
    assert cmds[0].startswith("touchswarm behaviour new chain")
    assert cmds[-1].startswith("touchswarm behaviour check")
    for cmd in cmds:
        argv = shlex.split(cmd.replace("/tmp", str(tmp_path))
                           .replace("/dev/ttyACM0", micropython_device.path))
        assert argv[0] == "touchswarm"
        rc = main(argv[1:])
        out = capsys.readouterr().out
        assert rc == 0, (cmd, out[-2000:])
    assert out.rstrip().endswith("behaviour check: PASS")
    assert "NOT RUN" not in out and "FAIL" not in out
    assert (tmp_path / "chain.dbc").exists() and (tmp_path / "chain-sweep" / "sweep.csv").exists()


@pytest.mark.parametrize("name", ["thesis", "aggregate"])
def test_behaviour_check_of_the_shipped_behaviours_passes(
        name: str, micropython_device, capsys: pytest.CaptureFixture[str]) -> None:
    rc = main(["behaviour", "check", name, "--ticks", "300", "--port", micropython_device.path])
    out = capsys.readouterr().out
    assert re.findall(r"^  (\w+)\s+PASS", out, re.M) == ["load", "run", "sweep", "firmware", "can",
                                                          "dbc", "bus", "deploy", "mission"], out
    assert rc == 0 and out.rstrip().endswith("behaviour check: PASS")
