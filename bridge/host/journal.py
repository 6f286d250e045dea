"""SQLite journal of the host: every report that changed what its
coordinator knows, and every decision the host acts on, in one order.

Opened in WAL mode with synchronous=FULL; every write is committed before the
call returns. The host writes a report before it sends the report's ACK, and
a decision (for the thesis: convergence, each transport step, delivery, each
HALT) before it sends the decision's command, so whatever a robot was told
survives a SIGKILL (and a power cut) of the host process.

Behaviour-neutral (layout version 2):
- `reports`: (id, node, kind, tick, f1..f6), the message's fields in the
  order messages.MESSAGES (or the behaviour's spec.MESSAGES) declares them;
  a view per reported message, `reports_<name>` (reports_touch,
  reports_hello, reports_leave, ...), names the columns as that table does.
  Which reports a coordinator journals is its own rule
  (firmware_logic/roster.py): a HELLO of a new node, an accepted TOUCH, ...
- `decisions`: (id, tick, kind, state, after): `state` is the snapshot the
  host needs to go on from there (JSON, `HostProcess.snapshot`), `after`
  the last report journalled before it.
- `meta`: the behaviour the journal belongs to and the layout version.
- `rejected`: reports the coordinator refused (node, kind, tick, reason,
  fields as JSON), the first REJECTED_KEPT of each reason: evidence, never
  replayed (additive, like `live`).
- `live`: the latest live view (robots' last HEARTBEAT poses, bad-frame
  counters), overwritten every few ticks for `touchswarm view`; never
  replayed, not needed to resume (the table is additive: layout version 2).
A resumed host replays the reports in order into a fresh coordinator,
adopting each decision's snapshot at its place (`entries`). Journals of
layout version 1 (a thesis-only `touches` table, before this layout) are
refused in one line naming the version.
"""

from __future__ import annotations

import fcntl
import json
import os
import sqlite3
from pathlib import Path
from typing import Any, NamedTuple, Union

from bridge.errors import BridgeError
from firmware_logic import messages as msg


DEFAULT_BEHAVIOUR = "thesis"
VERSION = 2
MAX_FIELDS = 6          # messages.check: at most 6 fields fit a frame
REJECTED_KEPT = 100     # refused reports journalled per reason (the rest only counted)
FIELD_COLUMNS = tuple("f%d" % (i + 1) for i in range(MAX_FIELDS))

SCHEMA = """
CREATE TABLE IF NOT EXISTS reports (id INTEGER PRIMARY KEY AUTOINCREMENT,
    node INTEGER NOT NULL, kind INTEGER NOT NULL, tick INTEGER NOT NULL,
    %s);
CREATE TABLE IF NOT EXISTS decisions (id INTEGER PRIMARY KEY AUTOINCREMENT,
    tick INTEGER NOT NULL, kind TEXT NOT NULL, state TEXT NOT NULL,
    after INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS live (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS rejected (id INTEGER PRIMARY KEY AUTOINCREMENT,
    node INTEGER NOT NULL, kind INTEGER NOT NULL, tick INTEGER NOT NULL,
    reason TEXT NOT NULL, fields TEXT NOT NULL);
""" % ", ".join(c + " INTEGER" for c in FIELD_COLUMNS)


class JournalError(BridgeError):
    """The journal cannot be opened, read or written (names the file)."""


class Report(NamedTuple):
    node: int
    kind: int
    fields: tuple[int, ...]
    tick: int


class Decision(NamedTuple):
    tick: int
    kind: str               # the coordinator's name for it (thesis: converged, step, ...)
    state: dict[str, Any]   # HostProcess.snapshot() after the decision


Entry = Union[Report, Decision]


def _ints(v: Any) -> bool:
    # a snapshot's values: integers (flags as JSON booleans) and lists of them
    return isinstance(v, int) or (isinstance(v, list) and all(isinstance(x, int) for x in v))


class Journal:
    def __init__(self, path: str | Path, readonly: bool = False) -> None:
        """readonly: only read a journal a host may be writing (`touchswarm
        view`); the file must exist and hold a journal's tables. A writer
        holds an exclusive lock on the file (flock, beside SQLite's own
        locks) until close(): one writer per journal; a second one is
        refused in one line."""
        self.path = Path(path)
        self.db: sqlite3.Connection | None = None
        self.live_db: sqlite3.Connection | None = None     # set_live's own connection
        self.lock_fd: int | None = None
        if readonly:
            self._open_readonly()
            return
        try:
            self.lock_fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as err:
            raise JournalError(f"cannot open journal {self.path}: {err.strerror}") from None
        try:
            fcntl.flock(self.lock_fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(self.lock_fd)
            self.lock_fd = None
            raise JournalError(f"journal {self.path} is in use by another host (one writer "
                               f"per journal); stop that host first, or give another "
                               f"--journal") from None
        try:
            self.db = sqlite3.connect(str(self.path), isolation_level=None, timeout=5.0,
                                      check_same_thread=False)
            mode = self.db.execute("PRAGMA journal_mode=WAL").fetchone()[0]
            if mode.lower() != "wal":
                raise JournalError(f"{self.path}: SQLite refused WAL mode ({mode})")
            self.db.execute("PRAGMA synchronous=FULL")
            tables = {r[0] for r in self.db.execute(
                "SELECT name FROM sqlite_master WHERE type = 'table'")}
            if "meta" in tables:
                self._check_version()
            self._check_layout_1(tables)
            self.db.executescript(SCHEMA)
            self.db.execute("INSERT OR IGNORE INTO meta VALUES ('version', ?)", (str(VERSION),))
        except (sqlite3.Error, JournalError) as err:
            self.close()
            if isinstance(err, JournalError):
                raise
            raise JournalError(f"cannot open journal {self.path}: {err}") from err

    def _open_readonly(self) -> None:
        try:
            self.db = sqlite3.connect(f"{self.path.resolve().as_uri()}?mode=ro", uri=True,
                                      isolation_level=None, timeout=5.0,
                                      check_same_thread=False)
            tables = {r[0] for r in self.db.execute(
                "SELECT name FROM sqlite_master WHERE type = 'table'")}
        except sqlite3.Error as err:
            self.close()
            raise JournalError(f"cannot open journal {self.path}: {err}") from err
        missing = {"reports", "decisions", "meta"} - tables
        try:
            self._check_layout_1(tables)
        except JournalError:
            self.close()
            raise
        if missing:
            self.close()
            raise JournalError(f"{self.path} is not a host journal (no {', '.join(sorted(missing))} "
                               f"table{'s' if len(missing) > 1 else ''})")
        try:
            self._check_version()
        except JournalError:
            self.close()
            raise

    def _check_layout_1(self, tables: set[str]) -> None:
        if "touches" in tables:
            raise JournalError(
                f"journal {self.path} has layout version 1 (the thesis-only touches "
                f"table); this host reads version {VERSION}: finish that mission with "
                f"the touchswarm that wrote it, or start a new journal")

    def _check_version(self) -> None:
        """A journal of a newer layout is refused in one line (this host
        would misread it); so is an unreadable version."""
        assert self.db is not None
        try:
            rows = self.db.execute("SELECT value FROM meta WHERE key = 'version'").fetchall()
        except sqlite3.Error as err:
            raise JournalError(f"journal {self.path}: {err}") from None
        if not rows:
            return
        try:
            version = int(rows[0][0])
        except (TypeError, ValueError):
            raise JournalError(f"journal {self.path}: layout version {rows[0][0]!r} is not a "
                               f"number; not a journal this host wrote") from None
        if version != VERSION:
            raise JournalError(f"journal {self.path} has layout version {version}; this host "
                               f"reads version {VERSION}: use the touchswarm that wrote it, or "
                               f"start a new journal")

    def held(self) -> int:
        """Reports and decisions journalled (0: a fresh journal)."""
        return (self._sql("SELECT COUNT(*) FROM reports")[0][0]
                + self._sql("SELECT COUNT(*) FROM decisions")[0][0])

    def _sql(self, sql: str, args: tuple = ()) -> list[tuple]:
        """Run one statement (committed on return: autocommit); every SQLite
        error becomes a JournalError naming the file."""
        if self.db is None:
            raise JournalError(f"journal {self.path} is closed")
        try:
            return self.db.execute(sql, args).fetchall()
        except sqlite3.Error as err:
            raise JournalError(f"journal {self.path}: {err}") from err

    def _views(self) -> None:
        """One view per reported message, its columns named as the message
        table names its fields (the behaviour's kinds are declared by now)."""
        for kind, name, direction, _, fields in msg.rows():
            if direction != msg.UP:
                continue
            cols = ", ".join(f"{c} AS {f[0]}" for c, f in zip(FIELD_COLUMNS, fields))
            self._sql(f"CREATE VIEW IF NOT EXISTS reports_{name.lower()} AS SELECT id, node, "
                      f"tick, {cols} FROM reports WHERE kind = {kind}")

    def add_report(self, node: int, kind: int, fields: tuple[int, ...], tick: int,
                   commit: bool = True) -> None:
        """One report as the coordinator accepted it (before its ACK).
        commit=False: in a transaction that `commit()` ends (the host commits
        a tick's reports at once, before that tick's commands go out)."""
        if len(fields) > MAX_FIELDS:
            raise JournalError(f"journal {self.path}: a {len(fields)}-field report "
                               f"(at most {MAX_FIELDS})")
        row = tuple(fields) + (None,) * (MAX_FIELDS - len(fields))
        if not commit:
            self._begin()
        self._sql(f"INSERT INTO reports (node, kind, tick, {', '.join(FIELD_COLUMNS)}) "
                  f"VALUES (?, ?, ?, {', '.join('?' * MAX_FIELDS)})", (node, kind, tick) + row)

    def _begin(self) -> None:
        if self.db is not None and not self.db.in_transaction:
            self._sql("BEGIN IMMEDIATE")

    def commit(self) -> None:
        """Make every write since the last commit durable (one fsync)."""
        if self.db is not None and self.db.in_transaction:
            self._sql("COMMIT")

    def add_rejected(self, node: int, kind: int, fields: tuple, tick: int, reason: str,
                     commit: bool = True) -> None:
        """A report the coordinator refused, as evidence (never replayed)."""
        if not commit:
            self._begin()
        self._sql("INSERT INTO rejected (node, kind, tick, reason, fields) VALUES "
                  "(?, ?, ?, ?, ?)", (node, kind, tick, reason, json.dumps(list(fields))))

    def rejected(self) -> list[tuple[int, int, int, str, tuple]]:
        """(node, kind, tick, reason, fields) of the refused reports journalled."""
        try:
            rows = self._sql("SELECT node, kind, tick, reason, fields FROM rejected "
                             "ORDER BY id")
        except JournalError:
            return []          # a journal written before the table (read only)
        return [(n, k, t, r, tuple(json.loads(f))) for n, k, t, r, f in rows]

    def behaviour(self) -> str:
        rows = self._sql("SELECT value FROM meta WHERE key = 'behaviour'")
        return rows[0][0] if rows else DEFAULT_BEHAVIOUR

    def bind(self, behaviour: str) -> None:
        """Mark the journal as `behaviour`'s; JournalError if it holds another's
        reports (its coordinator would read them with other rules)."""
        has = self._sql("SELECT COUNT(*) FROM reports")[0][0] or \
            self._sql("SELECT COUNT(*) FROM meta WHERE key = 'behaviour'")[0][0]
        if has and self.behaviour() != behaviour:
            raise JournalError(f"journal {self.path} was written by a host of behaviour "
                               f"{self.behaviour()!r}, not {behaviour!r}; resume it with "
                               f"--behaviour {self.behaviour()}")
        self._sql("INSERT OR REPLACE INTO meta VALUES ('behaviour', ?)", (behaviour,))
        self._views()

    def add_decision(self, tick: int, kind: str, state: dict[str, Any]) -> None:
        self._sql("INSERT INTO decisions (tick, kind, state, after) VALUES (?, ?, ?, "
                  "(SELECT COALESCE(MAX(id), 0) FROM reports))",
                  (tick, kind, json.dumps(state, sort_keys=True)))

    def reports(self, kind: int | None = None) -> list[Report]:
        """The journalled reports in journal order (of one kind)."""
        where = "" if kind is None else f" WHERE kind = {int(kind)}"
        return [self._report(r) for r in self._sql(
            f"SELECT node, kind, tick, {', '.join(FIELD_COLUMNS)} FROM reports{where} "
            "ORDER BY id")]

    def _report(self, r: tuple) -> Report:
        # a field's column is NULL past the message's last field
        fields = tuple(v for v in r[3:] if v is not None)
        if not all(type(v) is int for v in (r[0], r[1], r[2]) + fields) \
                or (r[1] in msg.SCHEMA and len(fields) != len(msg.SCHEMA[r[1]][1])):
            raise JournalError(f"journal {self.path}: a malformed report (node {r[0]!r}, kind "
                               f"{r[1]!r}, tick {r[2]!r}, fields {list(fields)!r}); not a "
                               f"journal this host can resume")
        return Report(r[0], r[1], fields, r[2])

    def nodes(self) -> dict[int, tuple[int, int]]:
        """node -> (model, power) of each journalled HELLO."""
        return {r.node: (r.fields[0], r.fields[1]) for r in self.reports(msg.HELLO)}

    def entries(self) -> list[Entry]:
        """Reports and decisions in the order they were journalled."""
        reports = self._sql(f"SELECT node, kind, tick, {', '.join(FIELD_COLUMNS)}, id "
                            "FROM reports ORDER BY id")
        decisions = self._sql("SELECT tick, kind, state, after FROM decisions ORDER BY id")
        out: list[Entry] = []
        i = 0
        for r in reports:
            while i < len(decisions) and decisions[i][3] < r[-1]:
                out.append(self._decision(decisions[i]))
                i += 1
            out.append(self._report(r[:-1]))
        out.extend(self._decision(d) for d in decisions[i:])
        return out

    def decisions(self) -> list[Decision]:
        return [self._decision(r) for r in
                self._sql("SELECT tick, kind, state FROM decisions ORDER BY id")]

    def _decision(self, row: tuple) -> Decision:
        try:
            state = json.loads(row[2])
        except (ValueError, TypeError) as err:
            raise JournalError(f"journal {self.path}: unreadable decision at tick "
                               f"{row[0]}: {err}") from None
        why = self._bad_state(state)
        if why is None and type(row[0]) is not int:
            why = f"tick {row[0]!r} is not an integer"
        if why is not None:
            raise JournalError(f"journal {self.path}: a malformed decision snapshot at tick "
                               f"{row[0]!r} ({why}); not a journal this host can resume")
        return Decision(int(row[0]), str(row[1]), state)

    @staticmethod
    def _bad_state(state: Any) -> str | None:
        """Why a decision's snapshot is not {"host": {...}, "coordinator":
        {...}} of integers and lists of integers, or None."""
        if not isinstance(state, dict):
            return f"{type(state).__name__} instead of an object"
        for part in ("host", "coordinator"):
            v = state.get(part, {})
            if not isinstance(v, dict):
                return f"{part!r} is {type(v).__name__}, not an object"
            for k, x in v.items():
                if not _ints(x):
                    return f"{part}.{k} = {json.dumps(x)[:40]}, not an integer"
        return None

    def last_tick(self) -> int:
        """The latest host tick anything was journalled at."""
        v = self._sql("SELECT MAX(t) FROM (SELECT MAX(tick) AS t FROM reports "
                      "UNION ALL SELECT MAX(tick) FROM decisions)")[0][0]
        return int(v) if v is not None else 0

    def set_outcome(self, outcome: str, reason: str, tick: int) -> None:
        """How the host's run ended (HostProcess.outcome), durable like a
        decision: the meta key `outcome`, {"outcome", "reason", "tick"}."""
        self._sql("INSERT OR REPLACE INTO meta VALUES ('outcome', ?)",
                  (json.dumps({"outcome": outcome, "reason": reason, "tick": tick},
                              sort_keys=True),))

    def outcome(self) -> dict[str, Any] | None:
        """The last run's outcome (set_outcome); None when no run ended."""
        rows = self._sql("SELECT value FROM meta WHERE key = 'outcome'")
        if not rows:
            return None
        try:
            v = json.loads(rows[0][0])
        except ValueError:
            v = None
        if not isinstance(v, dict) or not isinstance(v.get("outcome"), str):
            raise JournalError(f"journal {self.path}: unreadable outcome {rows[0][0][:60]!r}")
        return v

    def set_live(self, view: dict[str, Any]) -> None:
        """Overwrite the live view (what `touchswarm view` shows besides the
        reports). Not durable, unlike everything else here: its own connection
        commits without waiting for the disk (a synchronous commit costs ~9 ms,
        most of a host tick); a crash may lose the last one, which only the
        view reads."""
        if self.db is None:
            raise JournalError(f"journal {self.path} is closed")
        self.commit()           # one writer at a time: the batch first
        try:
            if self.live_db is None:
                self.live_db = sqlite3.connect(str(self.path), isolation_level=None,
                                               timeout=5.0, check_same_thread=False)
                self.live_db.execute("PRAGMA synchronous=OFF")
            self.live_db.execute("INSERT OR REPLACE INTO live VALUES ('now', ?)",
                                 (json.dumps(view, sort_keys=True),))
        except sqlite3.Error as err:
            raise JournalError(f"journal {self.path}: {err}") from err

    def live(self) -> dict[str, Any] | None:
        """The latest live view; None when none was written (or the journal
        predates the live table)."""
        try:
            rows = self._sql("SELECT value FROM live WHERE key = 'now'")
        except JournalError:
            return None        # a read-only journal written before the live table
        return json.loads(rows[0][0]) if rows else None

    def copy_from(self, other: "Journal") -> None:
        """Carry another journal's reports and decisions over in their order
        (resume into a new file)."""
        self.bind(other.behaviour())
        for e in other.entries():
            if isinstance(e, Report):
                self.add_report(*e)
            else:
                self.add_decision(*e)

    def close(self) -> None:
        """Idempotent; never raises; commits what a batch left open."""
        if self.db is not None and self.db.in_transaction:
            try:
                self.db.execute("COMMIT")
            except sqlite3.Error:
                pass
        for db in (self.live_db, self.db):
            if db is not None:
                try:
                    db.close()
                except sqlite3.Error:
                    pass      # nothing uncommitted: every write committed on return
        self.db = self.live_db = None
        if self.lock_fd is not None:
            os.close(self.lock_fd)       # after SQLite closed: releases the writer's lock
            self.lock_fd = None

    def __enter__(self) -> "Journal":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
