"""The host's SQLite journal: WAL, durable before ACK, restored on resume."""

import sqlite3

import pytest

from bridge.host.journal import Journal, JournalError
from bridge.host.process import HostProcess
from firmware_logic import messages as msg
from firmware_logic.behaviours.thesis.coordinator import Touch


class FakeTransport:
    def __init__(self):
        self.sent = []
        self.inbox = []

    def poll(self, timeout):
        out, self.inbox = self.inbox, []
        return out

    def send(self, node, kind, fields):
        self.sent.append((node, kind, tuple(fields)))

    def bad_frames(self):
        return {}

    def close(self):
        pass


def test_wal_and_roundtrip(tmp_path):
    p = tmp_path / "j.sqlite"
    with Journal(p) as j:
        j.add_node(3, 1, 100)
        j.add_touch(Touch(3, 1, 2, 3, 3, 3, 100, 17))
        j.add_touch(Touch(3, 1, 2, 3, 3, 3, 100, 17))     # idempotent
        assert j.touches()[0].as_tuple() == (3, 1, 2, 3, 3, 3, 100, 17)
        assert j.last_tick() == 17
    with sqlite3.connect(str(p)) as db:
        assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    with Journal(p) as j:
        assert j.nodes() == {3: (1, 100)} and len(j.touches()) == 1
    j.close()   # idempotent
    with pytest.raises(JournalError):
        j.touches()


def test_touch_is_journalled_before_its_ack(tmp_path):
    tr = FakeTransport()
    order = []
    with Journal(tmp_path / "j.sqlite") as j:
        h = HostProcess(tr, weight=500, journal=j)
        real = j.add_touch
        j.add_touch = lambda t: (order.append(("journal", t.node, len(tr.sent))), real(t))
        h.handle([(4, msg.HELLO, (1, 100, 1))])
        h.step()
        assert (4, msg.ACK, (0,)) in tr.sent and j.nodes() == {4: (1, 100)}
        h.handle([(4, msg.TOUCH, (1, 2, 2, 3, 2, 100))])
        acks_before = len(tr.sent)
        assert order == [("journal", 4, acks_before)]          # nothing sent yet
        h.step()
        assert tr.sent[-1] == (4, msg.ACK, (1,))
        # a duplicate is ACKed again but not journalled or counted again
        h.handle([(4, msg.TOUCH, (1, 2, 2, 3, 2, 100))])
        h.step()
        assert tr.sent[-1] == (4, msg.ACK, (1,)) and len(order) == 1
        assert h.coord.power == 100 and h.coord.duplicates == 1


def test_resume_restores_touches_and_nodes(tmp_path):
    p = tmp_path / "j.sqlite"
    with Journal(p) as j:
        h = HostProcess(FakeTransport(), weight=500, journal=j)
        h.handle([(4, msg.HELLO, (1, 100, 1)), (5, msg.HELLO, (1, 100, 1))])
        for _ in range(3):
            h.step()
        h.handle([(4, msg.TOUCH, (1, 2, 2, 3, 2, 100)), (5, msg.TOUCH, (1, 3, 3, 4, 3, 100))])
    tr = FakeTransport()
    with Journal(p) as j:
        h2 = HostProcess(tr, weight=500, journal=j)
        assert h2.resume(j) == 2
        assert h2.tick >= 3 and h2.coord.power == 200
        # robot 5 never got its ACK: its retransmission is a duplicate, re-ACKed
        h2.handle([(5, msg.TOUCH, (1, 3, 3, 4, 3, 100))])
        h2.step()
        assert tr.sent == [(5, msg.ACK, (1,))]
        assert h2.coord.power == 200 and h2.bad_frames() == {}
        assert len(j.touches()) == 2


def test_a_journal_without_displacement_columns_is_migrated(tmp_path):
    """Touches now keep the object's displacement at acceptance (mx, my); a
    journal written before has no such columns and reads as displacement 0."""
    p = tmp_path / "old.sqlite"
    with sqlite3.connect(str(p)) as db:
        db.executescript(
            "CREATE TABLE nodes (node INTEGER PRIMARY KEY, model INTEGER NOT NULL,"
            " power INTEGER NOT NULL);"
            "CREATE TABLE touches (node INTEGER NOT NULL, seq INTEGER NOT NULL,"
            " rx INTEGER NOT NULL, ry INTEGER NOT NULL, sx INTEGER NOT NULL,"
            " sy INTEGER NOT NULL, power INTEGER NOT NULL, tick INTEGER NOT NULL,"
            " PRIMARY KEY (node, seq));"
            "INSERT INTO nodes VALUES (3, 1, 100);"
            "INSERT INTO touches VALUES (3, 1, 2, 3, 3, 3, 100, 17);")
    with Journal(p) as j:
        (t,) = j.touches()
        assert t.as_tuple() == (3, 1, 2, 3, 3, 3, 100, 17) and (t.mx, t.my) == (0, 0)
        j.add_touch(Touch(4, 1, 2, 3, 3, 3, 100, 20, -2, -1))
    with Journal(p) as j:
        assert [(t.node, t.mx, t.my) for t in j.touches()] == [(3, 0, 0), (4, -2, -1)]
