"""A behaviour's studies (studies.py: named sweeps and their figures as
data, sim_backend/studies.py): a user's scaffold declares one and runs it
with `touchswarm sweep --study NAME` as docs/writing-a-behaviour.md
"Studies" says; a wrong one is one line naming the behaviour, the study and
the key; the thesis's are its own (--thesis and --preset faults|breeds are
aliases of its studies). Reference engine, few runs."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from bridge.cli import main
from sim_backend import studies, sweep

ROOT = Path(__file__).resolve().parents[1]
GUIDE = (ROOT / "docs" / "writing-a-behaviour.md").read_text()
SECTION = re.search(r"^## Studies$(.*?)(?=^## )", GUIDE, re.M | re.S).group(1)
STUDY = re.search(r"```python\n(.*?)```", SECTION, re.S).group(1)
COMMANDS = [line.split("#")[0].strip()
            for block in re.findall(r"```sh\n(.*?)```", SECTION, re.S)
            for line in block.splitlines() if line.split("#")[0].strip()]


def test_the_guides_study_runs_from_a_scaffold_and_draws_its_figure(tmp_path, capsys):
    assert len(COMMANDS) == 2
    new, run = (shlex.split(c.replace("/tmp", str(tmp_path))) for c in COMMANDS)
    assert main(new[1:]) == 0
    folder = tmp_path / new[3]
    (folder / "studies.py").write_text(STUDY)
    capsys.readouterr()
    assert main(run[1:]) == 0, COMMANDS[1]
    out = tmp_path / "quorum-out"
    rows = sweep.read_csv(out / "sweep.csv")
    assert [(r["experiment"], r["quorum"], r["seed"]) for r in rows] == \
        [("quorum", "20", "1"), ("quorum", "20", "2"), ("quorum", "50", "1"),
         ("quorum", "50", "2")]
    assert {r["agents"] for r in rows} == {"10"} and {r["maxTicks"] for r in rows} == {"300"}
    assert (out / "quorum.png").stat().st_size > 1000
    assert str(out / "quorum.png") in capsys.readouterr().out
    # listed with the behaviour's keys
    assert main(["scenarios", "--behaviour", str(folder)]) == 0
    listed = capsys.readouterr().out
    assert re.search(r"^  quorum +2 points x 2 seeds, until delivered; the ticks until", listed,
                     re.M), listed


@pytest.mark.parametrize("change, words", [
    (('"y": "home_tick"', ''), "figure 'quorum': no 'y'; a factor figure needs x, y"),
    (('"kind": "factor"', '"kind": "pie"'), "figure 'quorum': kind 'pie'; expected one of"),
    (('"seeds": 2', '"sede": 2'), "study 'quorum': unknown key 'sede'"),
    (('"seeds": 2', '"seeds": "2"'), "study 'quorum': seeds = 2; expected the count"),
    (('(20, 50)', '(20, 500)'),
     "study 'quorum': point 'quorum' (quorum=500): quorum: 500 is outside"),
    (('("agents", 10)', '("objectWeight", "heavy")'),
     "study 'quorum' set: objectWeight = 'heavy'; expected a number"),
    (('"about"', '"abut"'), "unknown key 'abut'"),
    (('STUDIES = (', 'STUDIES = (('), "studies.py: SyntaxError"),
    (('{"name": "quorum",', '{"name": "quorum", "until": "home",'),
     "until = 'home'; expected delivered or converged"),
])
def test_a_wrong_study_is_one_line_naming_behaviour_study_and_key(change, words, tmp_path,
                                                                   capsys):
    name = "bad"        # one name in every case: each folder is its own module
    assert main(["behaviour", "new", name, "--into", str(tmp_path)]) == 0
    (tmp_path / name / "studies.py").write_text(STUDY.replace(*change))
    capsys.readouterr()
    rc = main(["sweep", "--set", f"behaviour={tmp_path / name}", "--study", "quorum",
               "--engine", "reference", "--executor", "inline", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert rc == 2 and err.count("\n") == 1 and words in err, err
    assert "studies.py" in err or "study 'quorum'" in err
    assert not (tmp_path / "o" / "sweep.csv").exists()


def test_an_unknown_study_names_the_behaviours_studies(capsys):
    assert main(["sweep", "--study", "nope", "--out", "/nonexistent/never"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "study 'nope': behaviour 'thesis' declares no such study; " \
        "its studies: thesis, faults, breeds, scalability" in err
    assert main(["sweep", "--thesis", "--set", "behaviour=aggregate", "--out",
                 "/nonexistent/never"]) == 2
    assert "its studies: none (no studies.py in its folder)" in capsys.readouterr().err


def test_the_thesis_presets_are_its_studies():
    """--thesis and --preset faults|breeds name the thesis's studies; the
    fault study's goal mix is one point of it (robustness.why reads it)."""
    from sim_backend.robustness import study_point
    own = studies.of("thesis")
    assert list(own) == ["thesis", "faults", "breeds", "scalability"]
    t = own["thesis"]
    assert (len(t.points), t.seeds, t.until, dict(t.overrides)) == \
        (62, 150, "converged", {"maxTicks": 5000})
    assert [p.experiment for p in t.points].count("shapes") == 20
    assert {f["kind"] for f in t.figures} == {"factor", "shapes", "units", "touchmap"}
    assert study_point("faults", "goal", {"crowd": "block"}) == {
        "maxTicks": 3000, "faultWindow": 200, "lostAfter": 100, "deathRate": 0.25,
        "ignoreFieldRate": 0.1, "randomRate": 0.1, "crowd": "block"}


def test_study_options_clash_in_one_line(capsys):
    for argv, words in ((["--thesis", "--study", "faults"], "give one"),
                        (["--preset", "faults", "--grid", "deathRate=0.1"],
                         "--preset faults runs its own grid"),
                        (["--study", "breeds", "--save-experiment", "x.toml"],
                         "--study breeds is its own experiment")):
        assert main(["sweep", *argv]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and words in err, err
