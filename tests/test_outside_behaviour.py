"""A user's behaviour in a folder outside the repository, made by `behaviour
new` in tmp_path, through every step a user takes from there, as
docs/writing-a-behaviour.md gives them: run, sweep (the compiled soa engine
== the reference engine), firmware check (the real MicroPython), CAN record
and replay (moved elsewhere with its recording too), dbc, deploy to
MicroPython's unix port behind a pty, robots + host on a bus and a mission
with the board as one robot, the live view, the Python API; files that name
the folder (a scenario, an experiment, a sidecar) name it relative to
themselves and load it only when trusted; a mistake in the user's files is
one line naming the file and the line.

The behaviour is tests/test_behaviour_folder.spread_behaviour (the scaffold
edited: its own parameter, module, down message and measure): the same
source each time, so its soa step is the one tests/test_batch_engine.py
compiles (the cache is keyed by content, not by the folder), and this file
adds no compile.
"""

from __future__ import annotations

import csv
import json
import re
import shlex
import shutil
from pathlib import Path

import pytest

from bridge.cli import main
from hil_tests.conftest import micropython_device  # noqa: F401 - a fixture
from tests.test_behaviour_folder import edit, own_schema, scaffold, spread_behaviour  # noqa: F401
from tests.test_words import doc_commands

ROOT = Path(__file__).resolve().parents[1]
GUIDE = (ROOT / "docs" / "writing-a-behaviour.md").read_text()
SECTION = re.search(r"^## 5\. A folder of your own$(.*?)(?=^## )", GUIDE, re.M | re.S).group(1)
SMALL = ["--set", "maxTicks=400"]


def block(kind: str) -> list[str]:
    return re.findall(rf"```{kind}\n(.*?)```", SECTION, re.S)


def outside(folder: Path) -> Path:
    assert not folder.resolve().is_relative_to(ROOT), folder
    return folder


def one_line(capsys: pytest.CaptureFixture[str], *needles: str) -> str:
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    for n in needles:
        assert n in err, err
    return err


def rows(path: Path) -> list[dict]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_the_guides_own_folder_section_runs_as_written(
        tmp_path: Path, capsys: pytest.CaptureFixture[str],
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Section 5's commands, its scenario file and its Python, with /tmp/work a
    folder of the test's; the folder with its files then moves, and the
    experiment still finds the behaviour beside it."""
    work = tmp_path / "work"
    work.mkdir()
    outside(work)
    cmds = doc_commands("writing-a-behaviour.md", "5. A folder of your own")
    argv = [shlex.split(c.replace("/tmp/work", str(work)))[1:] for c in cmds]
    assert [a[:2] for a in argv] == [["behaviour", "new"], ["run", "--scenario"],
                                     ["sweep", "--set"], ["sweep", str(work / "exp.toml")]]
    assert main(argv[0]) == 0
    assert f"use it as --behaviour {work / 'mine'}" in capsys.readouterr().out
    (work / "mine.toml").write_text(block("toml")[0])

    # the scenario names the folder beside it: refused untrusted, run trusted
    assert main(argv[1][:3] + SMALL) == 2
    one_line(capsys, "names the behaviour folder", "--trust-behaviour")
    assert main(argv[1] + SMALL + ["--json"]) in (0, 1)
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert s["robots"] == 12 and s["quorum"] == 60 and "stopped" in s

    assert main(argv[2] + SMALL + ["--seeds", "2", "--engine", "reference", "--executor",
                                   "inline", "--no-plots", "--out", str(work / "sw")]) == 0
    assert 'behaviour = "mine"' in (work / "exp.toml").read_text()

    # the folder, its scenario and its experiment move together; run from elsewhere
    moved = tmp_path / "moved"
    shutil.move(str(work), str(moved))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    four = shlex.split(cmds[3].replace("/tmp/work", str(moved)))[1:]
    capsys.readouterr()
    assert main(four[:2] + ["--out", str(tmp_path / "sw2")]) == 2
    one_line(capsys, f"experiment {moved / 'exp.toml'}", str(moved / "mine"),
             "--trust-behaviour")
    assert main(four + ["--out", str(tmp_path / "sw2")]) == 0
    got = rows(tmp_path / "sw2" / "sweep.csv")
    assert sorted((r["quorum"], r["seed"]) for r in got) == [
        ("50", "1"), ("50", "2"), ("80", "1"), ("80", "2")]
    assert {r["behaviour"] for r in got} == {str(moved / "mine")}

    exec(compile(block("python")[0].replace("/tmp/work", str(moved)), "guide", "exec"), {})


def test_every_step_from_the_folder(tmp_path: Path, micropython_device,  # noqa: F811
                                    capsys: pytest.CaptureFixture[str],
                                    monkeypatch: pytest.MonkeyPatch) -> None:
    spread = outside(spread_behaviour(tmp_path))
    sc = ["--behaviour", str(spread), "--set", "fleeTicks=9", *SMALL]

    # run, by absolute and by relative path
    assert main(["run", *sc, "--json"]) == 0
    s = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert s["fleeTicks"] == 9 and s["nudges"] >= 1, s
    monkeypatch.chdir(spread.parent)
    assert main(["run", "--behaviour", "./spread", "--set", "fleeTicks=9", *SMALL,
                 "--json"]) == 0
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1]) == s

    # its records speak of no power, leader or convergence it does not have
    assert main(["run", *sc, "--out", str(tmp_path / "out")]) == 0
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == [
        "indstats.csv", "summary.json", "tt.csv", "world.png"]
    assert (tmp_path / "out" / "indstats.csv").read_text().startswith(
        "seed,node,tick,rx,ry,sx,sy\n")

    # sweep: the compiled soa engine gives the reference engine's runs
    swept = {}
    for engine in ("soa", "reference"):
        out = tmp_path / f"sw-{engine}"
        assert main(["sweep", "--set", f"behaviour={spread}", "--set", "maxTicks=400",
                     "--grid", "fleeTicks=3,9", "--seeds", "2", "--engine", engine,
                     "--executor", "inline", "--no-plots", "--out", str(out)]) == 0
        swept[engine] = rows(out / "sweep.csv")
    assert {r["engine"] for r in swept["soa"]} == {"soa"}
    for r in swept["soa"] + swept["reference"]:
        r.pop("engine")
    assert swept["soa"] == swept["reference"] and len(swept["soa"]) == 4
    assert any(r["nudges"] not in ("", "0") for r in swept["soa"])

    # firmware check: CPython == the real MicroPython, its down message sent
    capsys.readouterr()
    assert main(["firmware", "check", "--behaviour", str(spread), "--ticks", "1500"]) == 0
    out = capsys.readouterr().out
    assert "down messages the script sent: NUDGE" in out and "behaviour.moves" in out
    assert re.findall(r"states visited: (.*)", out) == ["search climb stay halt flee"] * 2
    assert out.rstrip().endswith("firmware check: PASS")

    # CAN: recorded beside the folder, replayed in the behaviour's words once
    # the recording and the folder moved together
    pack = tmp_path / "pack"
    shutil.copytree(spread, pack / "spread")
    assert main(["run", "--behaviour", str(pack / "spread"), "--set", "fleeTicks=9", *SMALL,
                 "--link", "can", "--record", str(pack / "spread.blf")]) == 0
    shutil.move(str(pack), str(tmp_path / "moved"))
    rec = tmp_path / "moved" / "spread.blf"
    capsys.readouterr()
    assert main(["replay", str(rec)]) == 2
    one_line(capsys, "names the behaviour folder", str(tmp_path / "moved" / "spread"))
    assert main(["replay", str(rec), "--trust-behaviour", str(tmp_path / "moved" / "spread")]) == 0
    line = capsys.readouterr().out
    assert re.search(r"\d+ touches, done at tick \d+; 0 divergences", line), line
    assert "delivered" not in line

    # dbc: its own message and its states, for cantools
    import cantools
    dbc = tmp_path / "spread.dbc"
    assert main(["dbc", "--behaviour", str(spread), "--out", str(dbc)]) == 0
    db = cantools.database.load_file(str(dbc))
    names = {m.name for m in db.messages}
    assert {"NUDGE_1", "LEAVE_1", "HEARTBEAT_1"} <= names
    beat = db.get_message_by_name("HEARTBEAT_1")
    assert "flee" in [str(v) for v in beat.get_signal_by_name("state").choices.values()]

    # deploy to MicroPython behind a pty: its package and its own parameter
    capsys.readouterr()
    assert main(["deploy", "--port", micropython_device.path, "--behaviour", str(spread),
                 "--set", "fleeTicks=9", "--config", "NODE=2"]) == 0
    assert "imported spread on the device and built its robot (Robot, 7 arguments" \
        in capsys.readouterr().out
    flash = micropython_device.flash
    assert (flash / "behaviour" / "moves.mpy").exists()
    assert not (flash / "behaviour" / "coordinator.mpy").exists()
    assert "ARGS = (2, 1, 1, 45, 2, 100, 9)" in (flash / "robot_config.py").read_text()

    # robots + host on a bus, and a mission with the board as robot 1
    assert main(["behaviour", "check", str(spread), "--ticks", "300", "--port",
                 micropython_device.path, "--only", "bus", "--only", "mission"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^  bus +PASS .*robots all halted", out, re.M), out
    assert re.search(r"^  mission +PASS .*robot 1 on the board", out, re.M), out

    # the live view, in its words
    shot = tmp_path / "view.png"
    assert main(["view", "--behaviour", str(spread), "--port", "0", "--screenshot",
                 str(shot)]) == 0
    assert shot.stat().st_size > 1000

    # the Python API, by the same key
    import touchswarm
    r = touchswarm.run(behaviour=str(spread), seed=1, fleeTicks=9, maxTicks=400)
    assert r.summary == s
    got = touchswarm.sweep({"fleeTicks": [3, 9]}, seeds=2, behaviour=str(spread),
                           engine="reference", progress=False, maxTicks=400)
    frame = got.to_dict("records") if hasattr(got, "to_dict") else got
    assert [row["nudges"] for row in frame] == [int(row["nudges"]) for row in
                                                swept["reference"]]


def broken(tmp_path: Path, name: str, file: str, old: str, new: str) -> Path:
    folder = outside(scaffold(tmp_path, name))
    edit(folder / file, old, new)
    return folder


SIGNATURE = "    def __init__(self, node, seed, model, vision_span, field_defiance, power):\n"
MISTAKES = {
    "syntax": ("spec.py", 'NAME = "syntax"\n', 'NAME = "syntax"\nx = (\n',
               r"spec\.py line \d+: SyntaxError: '\(' was never closed"),
    "raises": ("robot.py", "class Robot:\n", "raise RuntimeError('half-saved')\n\n\nclass Robot:\n",
               r"robot\.py line \d+: RuntimeError: half-saved"),
    "absolute": ("robot.py", "from .spec import CLIMB", "from absolute.spec import CLIMB",
                 r"robot\.py line \d+: ModuleNotFoundError: No module named 'absolute'; import "
                 r"the behaviour's own modules relatively"),
    "typo": ("__init__.py", "sc.fieldDefiance, 100)", "sc.fieldDefyance, 100)",
             r"__init__\.py line \d+: AttributeError: scenario has no key 'fieldDefyance'"),
}


@pytest.mark.parametrize("mistake", sorted(MISTAKES))
def test_a_mistake_in_the_users_files_is_one_line_naming_file_and_line(
        mistake: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from bridge.serial.pty import VirtualPort
    file, old, new, says = MISTAKES[mistake]
    folder = broken(tmp_path, mistake, file, old, new)
    says = re.escape(str(folder)) + "/" + says
    capsys.readouterr()
    with VirtualPort() as port:       # a port that exists; nothing may be sent to it
        for argv in (["run", "--behaviour", str(folder), *SMALL],
                     ["firmware", "check", "--behaviour", str(folder)],
                     ["sweep", "--set", f"behaviour={folder}", "--seeds", "1", "--engine",
                      "reference", "--executor", "inline", "--out", str(tmp_path / "sw")],
                     ["deploy", "--port", port.path, "--behaviour", str(folder), "--config",
                      "NODE=2"]):
            assert main(argv) == 2, argv
            assert re.search(says, one_line(capsys)), argv
        assert port.read() == b""
    import touchswarm
    with pytest.raises(ValueError, match=says):
        touchswarm.run(behaviour=str(folder), maxTicks=10)
    # behaviour check's load step says the same
    assert main(["behaviour", "check", str(folder), "--only", "load"]) == 1
    assert re.search(r"load +FAIL .*" + says, capsys.readouterr().out)


def test_behaviour_check_of_a_file_is_one_line(tmp_path: Path,
                                               capsys: pytest.CaptureFixture[str]) -> None:
    folder = scaffold(tmp_path, "filed")
    assert main(["behaviour", "check", str(folder / "spec.py")]) == 2
    one_line(capsys, "a file; give the behaviour's folder", str(folder))


def test_a_bug_in_the_users_step_is_one_line_naming_file_and_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The behaviour loads and fails while it runs (robot 1's 20th step),
    in this process and in a sweep's worker process alike: exit 1."""
    folder = broken(tmp_path, "buggy", "robot.py", "        self.ticks += 1\n",
                    "        self.ticks += 1\n        if self.ticks == 20:\n"
                    "            self.rxbuf[self.ticks] = 1\n")
    says = (re.escape(f"behaviour 'buggy' failed: {folder}/robot.py line ") + r"\d+"
            + re.escape(" in step: IndexError: list assignment index out of range"))
    capsys.readouterr()
    for argv in (["run", "--behaviour", str(folder), *SMALL],
                 ["run", "--behaviour", str(folder), *SMALL, "--link", "can"],
                 ["sweep", "--set", f"behaviour={folder}", "--seeds", "1", "--engine",
                  "reference", "--executor", "processes:1", "--no-plots", "--out",
                  str(tmp_path / "sw")],
                 ["firmware", "check", "--behaviour", str(folder)]):
        assert main(argv) == 1, argv
        assert re.search(says, one_line(capsys)), argv


def test_a_scaffold_made_here_is_named_as_a_path(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                 capsys: pytest.CaptureFixture[str]) -> None:
    """`--into .`: the hint names ./NAME (a bare NAME reads as an installed
    behaviour's), and that runs from here."""
    monkeypatch.chdir(tmp_path)
    assert main(["behaviour", "new", "here", "--into", "."]) == 0
    hint = capsys.readouterr().out.splitlines()[-1]
    assert hint.startswith("use it as --behaviour ./here;"), hint
    assert main(["run", "--behaviour", "./here", *SMALL, "--json"]) in (0, 1)
    assert json.loads(capsys.readouterr().out.strip().splitlines()[-1])["ticks"] > 0


def test_the_host_speaks_of_no_weight_or_leader_it_does_not_have(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """`touchswarm host --behaviour DIR`, resuming its journal on an adapter
    with no robots (3 ticks, then it gives up): the folder's journal resumes
    only with the folder on the command line, and neither the first line nor
    the result names the thesis's object weight or leader."""
    from bridge.host.journal import Journal
    from bridge.links import open_bus
    from firmware_logic import messages as msg
    folder = outside(scaffold(tmp_path, "quiet"))
    old = tmp_path / "old.sqlite"
    with Journal(old) as j:
        j.bind(str(folder))
        j.add_report(2, msg.HELLO, (1, 100, 1), 8)
        j.add_report(2, msg.TOUCH, (1, 3, 3, 4, 3, 100), 9)
    bus = f"slcan://{tmp_path / 'ada'}?settle_ms=0"
    with open_bus(f"slcan-pty://{tmp_path / 'ada'}"):        # an adapter, no robots
        assert main(["host", "--bus", bus, "--resume", str(old)]) == 2
        one_line(capsys, f"resume it with --behaviour {folder}")
        rc = main(["host", "--bus", bus, "--behaviour", str(folder), "--resume", str(old),
                   "--journal", str(tmp_path / "new.sqlite"), "--max-ticks", "3",
                   "--tick-ms", "1"])
    out = capsys.readouterr().out
    assert rc == 1
    first = next(ln for ln in out.splitlines() if ln.startswith("host on "))
    assert "home (-15,-15)" in first and "weight" not in first, first
    last = out.strip().splitlines()[-1]
    assert last.startswith("NOT done (") and ": 1 touches, ended at tick" in last, last
    assert "leader" not in last and "power" not in last
