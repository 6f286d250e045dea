"""The host's SQLite journal: WAL, durable before ACK, restored on resume."""

import sqlite3

import pytest

from bridge.host.journal import Journal, JournalError, Report
from bridge.host.process import HostProcess
from firmware_logic import messages as msg


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
        j.bind("thesis")
        j.add_report(3, msg.HELLO, (1, 100, 1), 2)
        j.add_report(3, msg.TOUCH, (1, 2, 3, 3, 3, 100), 17)
        j.add_decision(18, "converged", {"host": {"tick": 18}})
        assert j.reports(msg.TOUCH) == [Report(3, msg.TOUCH, (1, 2, 3, 3, 3, 100), 17)]
        assert j.last_tick() == 18
    with sqlite3.connect(str(p)) as db:
        assert db.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
        # the columns of each report's view are the message table's field names
        assert db.execute("SELECT node, seq, rx, ry, sx, sy, power, tick FROM "
                          "reports_touch").fetchall() == [(3, 1, 2, 3, 3, 3, 100, 17)]
        assert db.execute("SELECT model, power, version FROM reports_hello").fetchall() == [
            (1, 100, 1)]
    with Journal(p) as j:
        assert j.nodes() == {3: (1, 100)} and len(j.reports()) == 2
        assert [type(e).__name__ for e in j.entries()] == ["Report", "Report", "Decision"]
    j.close()   # idempotent
    with pytest.raises(JournalError):
        j.reports()


def test_touch_is_journalled_before_its_ack(tmp_path):
    tr = FakeTransport()
    order = []
    with Journal(tmp_path / "j.sqlite") as j:
        h = HostProcess(tr, weight=500, journal=j)
        real, commit = j.add_report, j.commit
        j.add_report = lambda node, kind, f, tick, **kw: (
            order.append(("journal", node, msg.SCHEMA[kind][0], len(tr.sent))),
            real(node, kind, f, tick, **kw))
        # a tick's reports are committed at once, before the tick's commands
        j.commit = lambda: (order.append(("commit", j.db.in_transaction, len(tr.sent))),
                            commit())
        h.handle([(4, msg.HELLO, (1, 100, 1))])
        assert order == [("journal", 4, "HELLO", 0)]          # before its ACK
        h.step()
        assert order[1] == ("commit", True, 0)                # durable before its ACK
        assert (4, msg.ACK, (0,)) in tr.sent and j.nodes() == {4: (1, 100)}
        h.handle([(4, msg.TOUCH, (1, 2, 2, 3, 2, 100))])
        acks_before = len(tr.sent)
        assert order[2:] == [("journal", 4, "TOUCH", acks_before)]     # nothing sent yet
        h.step()
        assert order[3] == ("commit", True, acks_before)
        assert tr.sent[-1] == (4, msg.ACK, (1,))
        # a duplicate is ACKed again but not journalled or counted again
        h.handle([(4, msg.TOUCH, (1, 2, 2, 3, 2, 100))])
        h.step()
        assert tr.sent[-1] == (4, msg.ACK, (1,))
        assert [o for o in order if o[0] == "journal"] == [o for o in order[:3] if
                                                           o[0] == "journal"]
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
        assert len(j.reports(msg.TOUCH)) == 2


def test_a_version_1_journal_is_refused_in_one_line(tmp_path, capsys):
    """Layout version 1 held thesis touches in their own columns; version 2
    holds any behaviour's reports. An old journal is refused, naming the
    version, before any port opens (docs/protocol.md)."""
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
    with pytest.raises(JournalError, match="layout version 1"):
        Journal(p)
    from bridge.cli import main
    assert main(["host", "--resume", str(p), "--bus", "slcan:///dev/null"]) == 2
    err = capsys.readouterr().err.strip()
    assert "layout version 1" in err and "version 2" in err and "\n" not in err


def test_resume_replays_reports_and_decisions_in_their_order(tmp_path):
    """A touch accepted during the transport is stored in the frame the
    object had then: the resumed host replays the leader's journalled
    HEARTBEATs and the decisions in order, and recognises the robot's
    retransmission as a duplicate, not a second touch."""
    p = tmp_path / "j.sqlite"
    tr = FakeTransport()
    with Journal(p) as j:
        h = HostProcess(tr, weight=100, journal=j)
        h.handle([(4, msg.HELLO, (1, 100, 1)), (5, msg.HELLO, (1, 100, 1))])
        h.step()
        h.handle([(4, msg.TOUCH, (1, 2, 2, 3, 2, 100))])
        h.step()                                      # converged: step 1 to robot 4
        c = h.coord
        assert c.step == 1 and c.converged_tick == h.tick
        dx, dy = c.dx, c.dy
        # the leader moved the object one step and says so; robot 5 touches
        # the moved object before the host's next tick (no decision between)
        late = (1, 3 + dx, 3 + dy, 4 + dx, 3 + dy, 100)
        h.handle([(4, msg.HEARTBEAT, (4, (2 + dx) * 256, (2 + dy) * 256, 0, 1)),
                  (5, msg.TOUCH, late)])
        h.step()
        assert (c.moved_x, c.moved_y) == (dx, dy) and len(c.touches) == 2
        state, segments = c.snapshot(), sorted(c.segments_now())
        assert (4 + dx, 3 + dy) in segments
        kinds = [d.kind for d in j.decisions()]
        assert kinds[:2] == ["converged", "step"]
    with Journal(p) as j:
        r = HostProcess(FakeTransport(), weight=100, journal=j)
        assert r.resume(j) == 2
        assert r.coord.snapshot() == state and sorted(r.coord.segments_now()) == segments
        r.handle([(5, msg.TOUCH, late)])
        r.step()
        assert r.coord.duplicates == 1 and r.coord.rejected == {}
