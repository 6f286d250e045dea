"""SQLite journal of the host: announced nodes and accepted touches.

Opened in WAL mode with synchronous=FULL; every write is committed before the
call returns, and the host calls it before sending the ACK, so a touch that
was acknowledged survives a SIGKILL (and a power cut) of the host process.
"""

from __future__ import annotations

import sqlite3
from pathlib import Path

from firmware_logic.behaviours.thesis.coordinator import Touch

SCHEMA = """
CREATE TABLE IF NOT EXISTS nodes (node INTEGER PRIMARY KEY, model INTEGER NOT NULL,
                                  power INTEGER NOT NULL);
CREATE TABLE IF NOT EXISTS touches (node INTEGER NOT NULL, seq INTEGER NOT NULL,
    rx INTEGER NOT NULL, ry INTEGER NOT NULL, sx INTEGER NOT NULL, sy INTEGER NOT NULL,
    power INTEGER NOT NULL, tick INTEGER NOT NULL, PRIMARY KEY (node, seq));
"""


class JournalError(Exception):
    pass


class Journal:
    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        try:
            self.db: sqlite3.Connection | None = sqlite3.connect(
                str(self.path), isolation_level=None, timeout=5.0,
                check_same_thread=False)
            mode = self.db.execute("PRAGMA journal_mode=WAL").fetchone()[0]
            if mode.lower() != "wal":
                raise JournalError(f"{self.path}: SQLite refused WAL mode ({mode})")
            self.db.execute("PRAGMA synchronous=FULL")
            self.db.executescript(SCHEMA)
        except sqlite3.Error as err:
            raise JournalError(f"cannot open journal {self.path}: {err}") from err

    def _conn(self) -> sqlite3.Connection:
        if self.db is None:
            raise JournalError(f"journal {self.path} is closed")
        return self.db

    def add_node(self, node: int, model: int, power: int) -> None:
        self._conn().execute("INSERT OR REPLACE INTO nodes VALUES (?, ?, ?)",
                             (node, model, power))

    def add_touch(self, t: Touch) -> None:
        self._conn().execute("INSERT OR IGNORE INTO touches VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                             t.as_tuple())

    def nodes(self) -> dict[int, tuple[int, int]]:
        return {n: (m, p) for n, m, p in
                self._conn().execute("SELECT node, model, power FROM nodes ORDER BY node")}

    def touches(self) -> list[Touch]:
        rows = self._conn().execute(
            "SELECT node, seq, rx, ry, sx, sy, power, tick FROM touches ORDER BY rowid")
        return [Touch(*r) for r in rows]

    def last_tick(self) -> int:
        v = self._conn().execute("SELECT MAX(tick) FROM touches").fetchone()[0]
        return int(v) if v is not None else 0

    def close(self) -> None:
        if self.db is not None:
            self.db.close()
            self.db = None

    def __enter__(self) -> "Journal":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
