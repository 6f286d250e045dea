"""Sweeps are journals: rows reach sweep.csv as runs return, an interrupted
sweep resumes with --resume and ends with every run exactly once, and a
sweep saved as an experiment file runs again from it."""

import json
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bridge.cli import main
from sim_backend import sweep

GRID = ["--grid", "fieldDefiance=1,4", "--grid", "movementModel=firefly,ant"]
ARGS = [*GRID, "--seeds", "3", "--set", "maxTicks=400", "--executor", "inline", "--chunk", "2",
        "--no-plots"]
TOTAL = 12


def sweep_cli(out: Path, *extra: str) -> int:
    return main(["sweep", *ARGS, "--out", str(out), *extra])


def keys(path: Path) -> list[tuple[str, str, str]]:
    return [sweep.run_key(r) for r in sweep.read_csv(path)]


@pytest.fixture(scope="module")
def full(tmp_path_factory) -> str:
    """sweep.csv of the whole sweep, never interrupted."""
    out = tmp_path_factory.mktemp("full")
    assert sweep_cli(out) == 0
    return (out / "sweep.csv").read_text()


def test_a_truncated_sweep_resumes_to_the_same_file(tmp_path, full, capsys):
    lines = full.splitlines(keepends=True)
    assert len(lines) == TOTAL + 1
    # 5 rows survived, and the 6th was cut off mid-write
    (tmp_path / "sweep.csv").write_text("".join(lines[:6]) + lines[6][:17])
    capsys.readouterr()
    assert sweep_cli(tmp_path, "--resume", "--json") == 0
    info = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert (info["resumed_runs"], info["new_runs"], info["runs"]) == (5, 7, TOTAL)
    assert (tmp_path / "sweep.csv").read_text() == full
    ks = keys(tmp_path / "sweep.csv")
    assert len(ks) == len(set(ks)) == TOTAL


def test_resume_of_a_finished_sweep_runs_nothing(tmp_path, full, capsys):
    (tmp_path / "sweep.csv").write_text(full)
    assert sweep_cli(tmp_path, "--resume", "--json") == 0
    info = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert (info["new_runs"], info["runs"]) == (0, TOTAL)
    assert (tmp_path / "sweep.csv").read_text() == full


def test_resume_refuses_a_file_of_another_sweep(tmp_path, full, capsys):
    (tmp_path / "sweep.csv").write_text(full)
    capsys.readouterr()
    # same grid and seeds, other maxTicks: the kept rows would not be this sweep's runs
    assert main(["sweep", *GRID, "--seeds", "3", "--set", "maxTicks=500", "--executor",
                 "inline", "--no-plots", "--out", str(tmp_path), "--resume"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "maxTicks=400" in err and "maxTicks=500" in err
    # a seed this sweep does not run
    assert main(["sweep", *GRID, "--seeds", "2", "--set", "maxTicks=400", "--executor",
                 "inline", "--no-plots", "--out", str(tmp_path), "--resume"]) == 2
    assert "is not a run of this sweep" in capsys.readouterr().err
    assert (tmp_path / "sweep.csv").read_text() == full


def test_a_finished_sweep_is_not_overwritten_by_accident(tmp_path, full, capsys):
    (tmp_path / "sweep.csv").write_text(full)
    assert sweep_cli(tmp_path) == 2
    assert "--resume finishes that sweep" in capsys.readouterr().err
    assert (tmp_path / "sweep.csv").read_text() == full
    (tmp_path / "sweep.csv").write_text(full.splitlines(keepends=True)[0])
    assert sweep_cli(tmp_path, "--overwrite") == 0
    assert (tmp_path / "sweep.csv").read_text() == full


def test_rows_are_appended_as_chunks_return():
    """on_rows sees each chunk's rows as it returns; together they are the
    result, each run once."""
    seen: list[list[dict]] = []
    rows = sweep.sweep(sweep.grid_points({"fieldDefiance": [1, 4]}), [1, 2, 3],
                       overrides={"maxTicks": 300}, chunk_size=2, on_rows=seen.append)
    assert [len(c) for c in seen] == [2, 2, 2]
    assert [r for c in seen for r in c] == rows


def wait_for(cond, proc, what: str, limit_s: float = 300.0) -> None:
    """Wait until cond() holds; fail if the process ended first or after a
    generous hang guard (the guard is no timing assumption: it only stops
    a hung test)."""
    deadline = time.monotonic() + limit_s
    while not cond():
        assert proc.poll() is None, f"the sweep ended (rc {proc.returncode}) before {what}"
        assert time.monotonic() < deadline, f"hang guard: no {what} in {limit_s} s"
        time.sleep(0.05)


def test_a_killed_sweep_resumes_without_repeating_or_losing_a_run(tmp_path):
    seeds = "1-15"
    args = ["sweep", "--grid", "fieldDefiance=1,4", "--seeds", seeds, "--set", "maxTicks=300",
            "--engine", "reference", "--executor", "inline", "--chunk", "1", "--no-plots"]
    out = tmp_path / "killed"
    csv_path = out / "sweep.csv"

    def rows_written() -> int:
        try:
            return max(0, csv_path.read_text().count("\n") - 1)
        except FileNotFoundError:
            return 0
    proc = subprocess.Popen([sys.executable, "-m", "bridge.cli", *args, "--out", str(out)],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    try:
        wait_for(lambda: rows_written() >= 1, proc, "first row in sweep.csv")
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == -signal.SIGKILL
    kept = rows_written()
    assert 1 <= kept < 30, "the kill came after the last run: nothing left to resume"
    assert main([*args, "--out", str(out), "--resume"]) == 0
    fresh = tmp_path / "fresh"
    assert main([*args, "--out", str(fresh)]) == 0
    assert csv_path.read_text() == (fresh / "sweep.csv").read_text()
    ks = keys(csv_path)
    assert len(ks) == len(set(ks)) == 30


def test_an_experiment_file_is_saved_and_runs_again(tmp_path, full, capsys):
    exp = tmp_path / "exp.toml"
    assert sweep_cli(tmp_path / "a", "--save-experiment", str(exp)) == 0
    assert (tmp_path / "a" / "sweep.csv").read_text() == full
    text = exp.read_text()
    assert 'out = "a"' in text and "[grid]" in text and "maxTicks = 400" in text
    # run it again from the file alone, into another folder
    assert main(["sweep", str(exp), "--out", str(tmp_path / "b")]) == 0
    assert (tmp_path / "b" / "sweep.csv").read_text() == full
    # a hand-written one
    (tmp_path / "hand.toml").write_text(
        'seeds = [1, 2, 3]\nexecutor = "inline"\nout = "c"\nchunk = 2\n'
        '[grid]\nfieldDefiance = [1, 4]\nmovementModel = ["firefly", "ant"]\n'
        '[set]\nmaxTicks = 400\n')
    assert main(["sweep", str(tmp_path / "hand.toml"), "--no-plots"]) == 0
    assert (tmp_path / "c" / "sweep.csv").read_text() == full


@pytest.mark.parametrize("text, message", [
    ('seedz = 3\n[grid]\nsigRadius = [3]\n', "unknown key 'seedz'"),
    ('seeds = 3\n', "no [grid] table"),
    ('seeds = true\n[grid]\nsigRadius = [3]\n', "seeds = True; expected a count N"),
    ('[grid]\nsigRadius = 3\n', "grid.sigRadius = 3; expected a non-empty list"),
    ('[grid]\nsigRadius = [3]\nnope = [1]\n', "--grid nope: unknown scenario key"),
    ('engine = "warp"\n[grid]\nsigRadius = [3]\n', "engine 'warp': expected one of"),
    ('seeds = [1, "x"]\n[grid]\nsigRadius = [3]\n', "expected a list of integer seeds"),
    ('[grid\n', "not valid TOML"),
])
def test_bad_experiment_files_are_one_line_errors(tmp_path, capsys, text, message):
    exp = tmp_path / "bad.toml"
    exp.write_text(text)
    assert main(["sweep", str(exp), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("touchswarm: error: ") and err.count("\n") == 1, err
    assert message in err, err
    assert not (tmp_path / "o").exists()
