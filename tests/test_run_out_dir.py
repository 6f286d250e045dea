"""`run --out D --trace D/t.csv`: --out is created before the other output
paths are checked, so they may lie in it; a refused path leaves no D behind."""

from bridge.cli import main

SMALL = ["--robots", "8", "--set", "maxTicks=40", "--seed", "1"]


def test_trace_and_record_inside_a_new_out_dir(tmp_path, capsys):
    d = tmp_path / "new" / "D"
    assert main(["run", *SMALL, "--out", str(d), "--trace", str(d / "t.csv"),
                 "--record", str(d / "r.blf")]) in (0, 1)
    assert (d / "t.csv").is_file() and (d / "r.blf").is_file() and (d / "world.png").is_file()
    assert len((d / "t.csv").read_text().splitlines()) > 1


def test_a_refused_path_leaves_no_new_out_dir(tmp_path, capsys):
    d = tmp_path / "new" / "D"
    assert main(["run", *SMALL, "--out", str(d), "--trace", str(d / "t.nosuchformat")]) == 2
    err = capsys.readouterr().err.strip()
    assert "--trace" in err and "\n" not in err
    assert not (tmp_path / "new").exists()
