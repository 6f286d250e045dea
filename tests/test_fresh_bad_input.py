"""Fresh bad input gets a one-line error, exit 2, before any
work: a device or a FIFO named as a scenario (a size limit and a
regular-file check on every small text file read), a seed range that would
not fit in memory, output paths that take an open but fail every write
(/dev/full), and more robots than a CAN node id carries."""

from __future__ import annotations

import os


from bridge.cli import main


def rows(tmp_path):
    fifo = tmp_path / "scenario.toml"
    os.mkfifo(fifo)
    big = tmp_path / "big.toml"
    big.write_text("# " + "x" * (1 << 20) + "\n")
    exp = tmp_path / "exp.toml"
    os.mkfifo(exp)
    return [
        (["run", "--scenario", "/dev/zero"], "'/dev/zero': a device or special file, not a regular file"),
        (["run", "--scenario", str(fifo)], "a FIFO, not a regular file"),
        (["run", "--scenario", str(big)], "more than the 1,048,576 allowed"),
        (["sweep", str(exp)], "a FIFO, not a regular file"),
        (["sweep", "--seeds", "1-99999999999999"], "seed 1000003 is outside 0..1000002"),
        (["dbc", "--out", "/dev/full"], "--out /dev/full: not a regular file"),
        (["run", "--trace", "/dev/full"], "--trace /dev/full: not a regular file"),
        (["run", "--link", "can", "--robots", "200"], "allowed 1..127"),
    ]


def test_fresh_bad_input_is_one_line_before_any_work(tmp_path, capsys) -> None:
    for argv, needle in rows(tmp_path):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert needle in err and "\n" not in err and "Traceback" not in err, (argv, err)
