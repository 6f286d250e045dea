"""`touchswarm sweep` without --grid runs one point (the scenario with its
--set overrides) over the seeds; a --set behaviour=... leaves the base
behaviour's own parameters behind, as `run --set` does."""

import csv

from bridge.cli import main


def rows(out):
    with open(out / "sweep.csv", newline="") as f:
        return list(csv.DictReader(f))


def test_a_sweep_without_grid_runs_one_point_over_the_seeds(tmp_path, capsys):
    out = tmp_path / "o"
    assert main(["sweep", "--seeds", "3", "--set", "maxTicks=60", "--engine", "reference",
                 "--executor", "inline", "--no-plots", "--out", str(out)]) == 0
    got = rows(out)
    assert [r["seed"] for r in got] == ["1", "2", "3"]
    assert {r["point"] for r in got} == {""} and {r["behaviour"] for r in got} == {"thesis"}
    assert "1 points x 3 seeds" in capsys.readouterr().out


def test_a_sweep_of_another_behaviours_folder_by_set(tmp_path, capsys):
    assert main(["behaviour", "new", "chain", "--into", str(tmp_path)]) == 0
    out = tmp_path / "o"
    assert main(["sweep", "--set", f"behaviour={tmp_path / 'chain'}", "--set", "quorum=50",
                 "--set", "maxTicks=80", "--seeds", "2", "--engine", "reference",
                 "--executor", "inline", "--no-plots", "--out", str(out)]) == 0
    got = rows(out)
    assert len(got) == 2 and got[0]["quorum"] == "50"
    assert "antBlocked" not in got[0]        # the thesis's own parameters are left behind
