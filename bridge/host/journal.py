"""SQLite journal of the host: announced nodes, accepted touches, and every
decision the host acts on.

Opened in WAL mode with synchronous=FULL; every write is committed before the
call returns. The host writes a touch before it sends the touch's ACK, and a
decision (convergence, each transport step, delivery, each HALT) before it
sends the decision's command, so whatever a robot was told survives a SIGKILL
(and a power cut) of the host process, and a resumed host goes on from the
last decision instead of starting the transport again.

A decision row holds the state the host needs to go on from there, as JSON
(`HostProcess.snapshot`): the coordinator's scalar attributes (step, dx, dy,
converged_tick, delivered_tick, ...) and the host's tick and HALT count.

Records (a thesis touch, an aggregation stop) share the TOUCH row layout;
they are read back as the journal's behaviour's RECORD class (its
coordinator module's). A record a behaviour withdraws (a robot that left its
stop) is marked released, not deleted, and is no longer restored. A journal
belongs to one behaviour (the `meta` table; journals written before it are
the thesis's), and a host of another behaviour refuses it.
"""

from __future__ import annotations

import importlib
import json
import sqlite3
from pathlib import Path
from typing import Any, NamedTuple

from bridge.errors import BridgeError
from firmware_logic import registry


DEFAULT_BEHAVIOUR = "thesis"    # what a journal without a `meta` row was written by


def record_class(behaviour: str) -> Any:
    """The class a journalled row is read back as: RECORD of the behaviour's
    coordinator module (the host process checks it is there)."""
    b = registry.load(behaviour)
    return importlib.import_module(b.module_name + ".coordinator").RECORD


Touch = Any   # a behaviour's RECORD (see record_class)

SCHEMA = """
CREATE TABLE IF NOT EXISTS nodes (node INTEGER PRIMARY KEY, model INTEGER NOT NULL,
                                  power INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS touches (node INTEGER NOT NULL, seq INTEGER NOT NULL,
    rx INTEGER NOT NULL, ry INTEGER NOT NULL, sx INTEGER NOT NULL, sy INTEGER NOT NULL,
    power INTEGER NOT NULL, tick INTEGER NOT NULL, mx INTEGER NOT NULL DEFAULT 0,
    my INTEGER NOT NULL DEFAULT 0, PRIMARY KEY (node, seq));
CREATE TABLE IF NOT EXISTS decisions (id INTEGER PRIMARY KEY AUTOINCREMENT,
    tick INTEGER NOT NULL, kind TEXT NOT NULL, state TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS released (node INTEGER NOT NULL, seq INTEGER NOT NULL,
    tick INTEGER NOT NULL, PRIMARY KEY (node, seq));
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
"""


class JournalError(BridgeError):
    """The journal cannot be opened, read or written (names the file)."""


class Decision(NamedTuple):
    tick: int
    kind: str               # converged, step, delivered, halt
    state: dict[str, Any]   # HostProcess.snapshot() after the decision


class Journal:
    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.db: sqlite3.Connection | None = None
        try:
            self.db = sqlite3.connect(str(self.path), isolation_level=None, timeout=5.0,
                                      check_same_thread=False)
            mode = self.db.execute("PRAGMA journal_mode=WAL").fetchone()[0]
            if mode.lower() != "wal":
                raise JournalError(f"{self.path}: SQLite refused WAL mode ({mode})")
            self.db.execute("PRAGMA synchronous=FULL")
            self.db.executescript(SCHEMA)
            self._migrate(self.db)
        except (sqlite3.Error, JournalError) as err:
            self.close()
            if isinstance(err, JournalError):
                raise
            raise JournalError(f"cannot open journal {self.path}: {err}") from err

    @staticmethod
    def _migrate(db: sqlite3.Connection) -> None:
        # journals from before touches kept the object's displacement at
        # acceptance (mx, my) lack those columns; 0 is exact for a touch
        # accepted before the transport began; for a later one only the
        # recognition of its retransmissions as duplicates is lost
        cols = {r[1] for r in db.execute("PRAGMA table_info(touches)")}
        for c in ("mx", "my"):
            if c not in cols:
                db.execute(f"ALTER TABLE touches ADD COLUMN {c} INTEGER NOT NULL DEFAULT 0")

    def _sql(self, sql: str, args: tuple = ()) -> list[tuple]:
        """Run one statement (committed on return: autocommit); every SQLite
        error becomes a JournalError naming the file."""
        if self.db is None:
            raise JournalError(f"journal {self.path} is closed")
        try:
            return self.db.execute(sql, args).fetchall()
        except sqlite3.Error as err:
            raise JournalError(f"journal {self.path}: {err}") from err

    def add_node(self, node: int, model: int, power: int) -> None:
        self._sql("INSERT OR REPLACE INTO nodes VALUES (?, ?, ?)", (node, model, power))

    def add_touch(self, t: Touch) -> None:
        self._add_row(t.as_tuple() + (t.mx, t.my))

    def _add_row(self, row: tuple) -> None:
        self._sql("INSERT OR IGNORE INTO touches (node, seq, rx, ry, sx, sy, power, tick, mx, my) "
                  "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)", row)

    def release(self, node: int, seq: int, tick: int) -> None:
        """The record (node, seq) was withdrawn; it is no longer restored."""
        self._sql("INSERT OR IGNORE INTO released VALUES (?, ?, ?)", (node, seq, tick))

    def behaviour(self) -> str:
        rows = self._sql("SELECT value FROM meta WHERE key = 'behaviour'")
        return rows[0][0] if rows else DEFAULT_BEHAVIOUR

    def bind(self, behaviour: str) -> None:
        """Mark the journal as `behaviour`'s; JournalError if it holds another's
        records (it would be read back as the wrong kind of record)."""
        has = self._sql("SELECT COUNT(*) FROM touches")[0][0] or \
            self._sql("SELECT COUNT(*) FROM meta")[0][0]
        if has and self.behaviour() != behaviour:
            raise JournalError(f"journal {self.path} was written by a host of behaviour "
                               f"{self.behaviour()!r}, not {behaviour!r}; resume it with "
                               f"--behaviour {self.behaviour()}")
        self._sql("INSERT OR REPLACE INTO meta VALUES ('behaviour', ?)", (behaviour,))

    def add_decision(self, tick: int, kind: str, state: dict[str, Any]) -> None:
        self._sql("INSERT INTO decisions (tick, kind, state) VALUES (?, ?, ?)",
                  (tick, kind, json.dumps(state, sort_keys=True)))

    def nodes(self) -> dict[int, tuple[int, int]]:
        return {n: (m, p) for n, m, p in
                self._sql("SELECT node, model, power FROM nodes ORDER BY node")}

    def rows(self, released: bool = False) -> list[tuple]:
        """The records' rows in journal order; without `released`, only those
        still held."""
        where = "" if released else \
            " WHERE NOT EXISTS (SELECT 1 FROM released r WHERE r.node = t.node AND r.seq = t.seq)"
        return self._sql("SELECT node, seq, rx, ry, sx, sy, power, tick, mx, my FROM touches t"
                         + where + " ORDER BY rowid")

    def touches(self) -> list[Touch]:
        """The records still held, as the journal's behaviour's RECORD."""
        record = record_class(self.behaviour())
        return [record(*r) for r in self.rows()]

    def decisions(self) -> list[Decision]:
        return [self._decision(r) for r in
                self._sql("SELECT tick, kind, state FROM decisions ORDER BY id")]

    def last_decision(self) -> Decision | None:
        rows = self._sql("SELECT tick, kind, state FROM decisions ORDER BY id DESC LIMIT 1")
        return self._decision(rows[0]) if rows else None

    def _decision(self, row: tuple) -> Decision:
        try:
            state = json.loads(row[2])
        except ValueError as err:
            raise JournalError(f"journal {self.path}: unreadable decision at tick "
                               f"{row[0]}: {err}") from err
        return Decision(int(row[0]), str(row[1]), state)

    def last_tick(self) -> int:
        """The latest host tick anything was journalled at."""
        v = self._sql("SELECT MAX(t) FROM (SELECT MAX(tick) AS t FROM touches "
                      "UNION ALL SELECT MAX(tick) FROM decisions)")[0][0]
        return int(v) if v is not None else 0

    def copy_from(self, other: "Journal") -> None:
        """Carry another journal's nodes, touches and decisions over (resume
        into a new file); decisions keep their order."""
        self.bind(other.behaviour())
        for n, (m, pw) in other.nodes().items():
            self.add_node(n, m, pw)
        for r in other.rows(released=True):
            self._add_row(r)
        for node, seq, tick in other._sql("SELECT node, seq, tick FROM released"):
            self.release(node, seq, tick)
        for d in other.decisions():
            self.add_decision(d.tick, d.kind, d.state)

    def close(self) -> None:
        """Idempotent; never raises."""
        db, self.db = self.db, None
        if db is not None:
            try:
                db.close()
            except sqlite3.Error:
                pass      # nothing uncommitted: every write committed on return

    def __enter__(self) -> "Journal":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
