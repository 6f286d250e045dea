"""One writer per journal, one mission per journal, and nothing in a journal
crashes the host: a second host on the same journal, a
finished mission appended to without --resume, a newer layout, an empty
file and every malformed snapshot or report are refused in one line (exit 2)
before any port opens."""

from __future__ import annotations

import json
import sqlite3

import pytest

from bridge.cli import main
from bridge.host.journal import Journal, JournalError
from firmware_logic import messages as msg
from tests.test_host_outcome import stalled_journal

BUS = ["--bus", "slcan:///dev/null"]     # never opened: the journal is refused first


def one_line(capsys, *needles: str) -> str:
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err, err
    for n in needles:
        assert n in err, err
    return err


def test_a_second_writer_is_refused_while_the_first_holds_the_journal(tmp_path, capsys) -> None:
    p = tmp_path / "j.sqlite"
    with Journal(p):
        with pytest.raises(JournalError, match="in use by another host"):
            Journal(p)
        assert main(["host", "--journal", str(p), *BUS]) == 2
        one_line(capsys, "in use by another host", str(p))
        Journal(p, readonly=True).close()          # a reader (`view`) is still welcome
    Journal(p).close()                             # released on close


def test_a_finished_mission_is_not_appended_to_without_resume(tmp_path, capsys) -> None:
    p = tmp_path / "j.sqlite"
    stalled_journal(p)
    capsys.readouterr()
    assert main(["host", "--journal", str(p), *BUS]) == 2
    one_line(capsys, "already holds", "ended stalled at tick", f"--resume {p}")


def test_a_newer_layout_and_an_empty_file_are_refused(tmp_path, capsys) -> None:
    p = tmp_path / "j.sqlite"
    with Journal(p) as j:
        j.bind("thesis")
    with sqlite3.connect(str(p)) as db:
        db.execute("UPDATE meta SET value = '3' WHERE key = 'version'")
    with pytest.raises(JournalError, match="layout version 3"):
        Journal(p)
    assert main(["host", "--resume", str(p), *BUS]) == 2
    one_line(capsys, "layout version 3", "reads version 2")
    empty = tmp_path / "empty.sqlite"
    empty.write_bytes(b"")
    assert main(["host", "--resume", str(empty), *BUS]) == 2
    one_line(capsys, "empty file (0 bytes)")
    assert empty.stat().st_size == 0                # not silently started afresh


def mission(path) -> None:
    with Journal(path) as j:
        j.bind("thesis")
        j.add_report(4, msg.HELLO, (1, 100, 1), 1)
        j.add_report(4, msg.TOUCH, (1, 2, 2, 3, 2, 100), 2)
        j.add_decision(3, "converged", {"host": {"tick": 3, "halts_sent": 0},
                                        "coordinator": {"converged_tick": 3, "step": 1}})


BAD = {
    "a list": ("decisions", "state", "[]", "list instead of an object"),
    "step text": ("decisions", "state", json.dumps(
        {"host": {"tick": 3}, "coordinator": {"step": "x"}}), "coordinator.step"),
    "converged null": ("decisions", "state", json.dumps(
        {"host": {"tick": 3}, "coordinator": {"converged_tick": None}}),
        "coordinator.converged_tick = null"),
    "host halts text": ("decisions", "state", json.dumps(
        {"host": {"halts_sent": "2"}, "coordinator": {}}), "host.halts_sent"),
    "list for an int": ("decisions", "state", json.dumps(
        {"host": {}, "coordinator": {"step": [1]}}), "sets step to [1]"),
    "not JSON": ("decisions", "state", "{", "unreadable decision"),
    "touch text": ("reports", "f2", "'far'", "a malformed report"),
    "touch field missing": ("reports", "f6", "NULL", "a malformed report"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_every_malformed_snapshot_or_report_is_one_line_on_resume(case, tmp_path, capsys) -> None:
    table, column, value, needle = BAD[case]
    p = tmp_path / "j.sqlite"
    mission(p)
    with sqlite3.connect(str(p)) as db:
        if value.startswith(("[", "{")):
            db.execute(f"UPDATE {table} SET {column} = ?", (value,))
        else:
            db.execute(f"UPDATE {table} SET {column} = {value} WHERE kind = {msg.TOUCH}")
    assert main(["host", "--resume", str(p), *BUS]) == 2
    one_line(capsys, needle, str(p))


def test_resuming_into_a_second_journal_that_holds_a_mission_is_refused(tmp_path, capsys) -> None:
    """`--resume A --journal B` carries A's mission over into B and goes on
    there; when B holds a mission of its own (ended, or another one in
    progress) the two would be mixed: refused in one line, B untouched.
    Into a new B, or --resume of B itself, is welcome."""
    a, b = tmp_path / "a.sqlite", tmp_path / "b.sqlite"
    mission(a)
    stalled_journal(b)
    capsys.readouterr()
    with Journal(b, readonly=True) as j:
        before = j.held()
    assert main(["host", "--resume", str(a), "--journal", str(b), *BUS]) == 2
    one_line(capsys, f"--journal {b} already holds", "ended stalled at tick",
             f"to resume {a} into", f"--resume {b}")
    with Journal(b, readonly=True) as j:
        assert j.held() == before
    mission(b2 := tmp_path / "b2.sqlite")            # a mission in progress
    assert main(["host", "--resume", str(a), "--journal", str(b2), *BUS]) == 2
    one_line(capsys, "a mission in progress")
    from bridge.commands.host import refuse_appending
    with Journal(tmp_path / "new.sqlite") as j:      # a new journal takes it
        refuse_appending(j, a)
