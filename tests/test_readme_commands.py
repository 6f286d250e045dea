"""README's commands, as written, at test size (tests/doc_commands.py lists
the options a test may add: fewer seeds and ticks, reference engine, in
process). Each command must exit 0 and leave what the README says it does.
Together with the tests that run the other README lines, conftest.py checks
after the whole suite that no README or guide command went unrun."""

from __future__ import annotations

import json
import shlex
from pathlib import Path

import pytest

from bridge.cli import main
from tests import doc_commands

# README line -> what the test adds to run it here (test size only)
SMALL = "--engine reference --executor inline"
CASES = {
    "run --scenario ant --seed 7": "",
    "run --scenario X --robots 24 --json": "",
    "run --set fieldDefiance=4 --set sigRadius=7": "",
    "run --scenario my.toml --out results/": "",
    "run --animate run.gif": "--set maxTicks=5",
    "run --scenario wall": "",
    "run --set agents=300": "--set maxTicks=30",
    "run --set wrap=true": "",
    "sweep --preset sizes": f"--seeds 1 --set maxTicks=3 {SMALL}",
    "run --scenario decoy --set recognise=true": "",
    "sweep --set behaviour=aggregate --grid quorum=60,90 --seeds 100":
        f"--seeds 2 --set maxTicks=60 {SMALL} --no-plots",
    "run --set behaviour=aggregate --link can --record agg.blf": "",
    "dbc --out touchswarm.dbc": "",
    "run --scenario netlogo": "",
    "view --scenario ant --seed 7": "--screenshot view.png --at-tick 30",
}


def test_every_case_is_a_readme_line_and_adds_only_test_size() -> None:
    lines = {line for name, line in doc_commands.documented() if name == "README.md"}
    assert set(CASES) <= lines, set(CASES) - lines
    for line, extra in CASES.items():
        doc = doc_commands.form(shlex.split(line))
        assert doc.covered_by(doc_commands.form(shlex.split(f"{line} {extra}"))), line


@pytest.mark.parametrize("line", [k for k in CASES if not k.startswith("view")])
def test_the_readme_command_runs(line: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                 capsys: pytest.CaptureFixture[str]) -> None:
    monkeypatch.chdir(tmp_path)
    if "my.toml" in line:          # the README's own scenario file, a small one
        Path("my.toml").write_text('name = "my"\nagents = 12\nobject = "L"\n')
    rc = main(shlex.split(line) + shlex.split(CASES[line]))
    out = capsys.readouterr()
    assert rc == 0 or (rc == 1 and "maxTicks" in CASES[line]), out.err
    if "--json" in line:
        assert json.loads(out.out.strip().splitlines()[-1])["robots"] == 24
    for made in [w for w in line.split() if "." in w and not w.startswith("-")]:
        if made.endswith((".toml",)):
            continue
        assert Path(made.split("=")[-1]).exists(), made
    if line.startswith("sweep"):
        assert Path("sweep-out/sweep.csv").exists() or list(tmp_path.rglob("sweep.csv"))


def test_the_readme_saves_an_experiment_and_resumes_it(tmp_path: Path,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """`sweep --grid sigRadius=3,5 --save-experiment exp.toml`, then
    `sweep exp.toml --resume`: the second finds every run done."""
    monkeypatch.chdir(tmp_path)
    assert main(["sweep", "--grid", "sigRadius=3,5", "--save-experiment", "exp.toml",
                 "--seeds", "2", "--set", "maxTicks=40", *SMALL.split(), "--no-plots"]) in (0, 1)
    assert Path("exp.toml").exists()
    csvs = list(tmp_path.rglob("sweep.csv"))
    assert len(csvs) == 1
    rows = csvs[0].read_text().splitlines()
    assert main(["sweep", "exp.toml", "--resume", "--no-plots"]) in (0, 1)
    assert csvs[0].read_text().splitlines() == rows and len(rows) == 1 + 4


def test_the_readme_view_renders_the_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`view --scenario ant --seed 7`, drawn once in headless Chromium."""
    monkeypatch.chdir(tmp_path)
    line = "view --scenario ant --seed 7"
    assert main(shlex.split(line) + shlex.split(CASES[line])) == 0
    assert Path("view.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
