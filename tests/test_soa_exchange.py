"""The soa engine's exchange compiled (sim_backend/batch/body.py `sift` and
`deliver`, entries of the generated module): the same messages dropped by
the same rule as exchange.Muting.drops, commands in each robot's inbox in
the order sent, a full ring refused whole with the typed error. One stepped
engine of the thesis behaviour (its step is the one every soa test loads)."""

import random

import numpy as np
import pytest

from firmware_logic import messages as msg
from sim_backend.batch import body as B
from sim_backend.batch.soa import INBOX, SoaEngine
from sim_backend.errors import EngineError
from sim_backend.exchange import BatchMutes, muting
from sim_backend.scenario import validate
from tests.test_exchange import Host
from tests.test_soa_deliver import inbox


@pytest.fixture(scope="module")
def stepped() -> SoaEngine:
    eng = SoaEngine([(validate({"agents": 3, "objectWeight": 2}), s) for s in (1, 2)])
    eng.step()                                   # the first tick loads the compiled entries
    return eng


def test_the_first_tick_loads_both_halves_compiled(stepped):
    assert stepped._sift_fn is not B.sift and stepped._deliver_fn is not B.deliver
    assert stepped._sift_fn is stepped.compiled.entry("sift")[0]


def dropped(m, node, kind, fields):
    """Muting.drops of a message as the exchange hands it over: a repeat
    clause compares as many fields as it declared."""
    return m.drops(node, kind, tuple(fields[:len(m.same)] if m.same is not None else fields))


def test_the_compiled_sift_drops_what_muting_drops_one_by_one(stepped):
    """Random declarations with and without a repeat clause over two runs,
    a sender sending several times a tick: the kept messages, their rows,
    and the clauses ended (the declaration's `same` ended with them) are
    what Muting.drops gives message by message in the order sent."""
    rng = random.Random(11)
    for _ in range(300):
        hosts, decl = [Host(), Host()], []
        for h in hosts:
            d = rng.choice([None, (5, {1, 2}, 3), (5, {1, 2, 3}, 3, (rng.randrange(2),)),
                            (4, {2}, 1, (1, 9)), (5, {1}, 2, (1, 9, 0, 0, 0, 0, 0))])
            decl.append(d)
            h.muted = (lambda d=d: d)
        run_of = np.array([0, 0, 0, 1, 1, 1])
        mutes = BatchMutes(hosts, [0, 3], [3, 3], run_of)
        n = rng.randrange(1, 12)
        robot = np.array([rng.randrange(6) for _ in range(n)])
        kind = np.array([rng.choice((4, 5)) for _ in range(n)])
        fields = np.array([[rng.randrange(2), 9, 0, 0, 0, rng.randrange(2)] for _ in range(n)])
        one = [muting(h) for h in hosts]
        want = [j for j, (r, k, f) in enumerate(zip(robot.tolist(), kind.tolist(),
                                                    fields.tolist()))
                if not dropped(one[r // 3], r % 3 + 1, k, f)]
        kept = np.full((n, 3 + B.FIELDS), -7, dtype=np.int64)
        ended = np.zeros(len(run_of) + 1, dtype=np.int64)
        k = stepped._sift_fn(robot, kind, fields, B.FIELDS, mutes.muted, mutes.repeats,
                             mutes.same, mutes.same_n, run_of, kept, ended, n)
        mutes.end(ended)
        assert kept[:k, 0].tolist() == want, (decl, robot, kind, fields)
        assert kept[:k, 1].tolist() == robot[want].tolist()
        assert kept[:k, 2].tolist() == kind[want].tolist()
        assert kept[:k, 3:].tolist() == fields[want].tolist()
        assert [m.same for m in mutes.mutes] == [m.same for m in one]


def test_an_ended_clause_is_marked_again_when_the_same_fields_are_declared_again():
    """The leader's other fields end its clause; the next tick() declaring
    the very same fields again sets it again (a new declaration), so its
    repeat is dropped again."""
    c = Host()
    c.muted = lambda: (5, {1, 2}, 3, (7,))
    mutes = BatchMutes([c], [0], [3], np.array([0, 0, 0]))
    fields = np.array([[8, 0], [7, 0]])
    assert mutes.keep(np.array([2, 2]), np.array([5, 5]), fields).tolist() == [True, True]
    assert mutes.mutes[0].same is None and mutes.repeats.tolist() == [-1, -1, -1]
    mutes.update(0, c)
    assert mutes.repeats.tolist() == [-1, -1, 5]
    assert mutes.keep(np.array([2, 2]), np.array([5, 5]), fields[::-1]).tolist() == [False, True]


def test_a_clause_no_message_can_repeat_drops_none():
    """Fields past a message's width, or not integers: the sender's messages
    of that kind are all handed over, as Muting.drops hands them over."""
    for same in ((1,) * (B.FIELDS + 1), (1.5,), (1 << 70,)):
        c = Host()
        c.muted = (lambda same=same: (5, {1}, 2, same))
        mutes = BatchMutes([c], [0], [2], np.array([0, 0]))
        assert mutes.same_n.tolist() == [-1]
        robot, kind = np.array([1, 1, 0]), np.array([5, 5, 5])
        fields = np.ones((3, B.FIELDS), dtype=np.int64)
        assert mutes.keep(robot, kind, fields).tolist() == [True, True, False]


def test_compiled_delivery_is_each_robots_commands_in_order(stepped):
    """A broadcast, several commands to one robot across a wrapping ring,
    shared fields objects: the compiled writes leave every ring as the
    Python rule (body.py `deliver` uncompiled) leaves a copy of it."""
    eng = stepped
    sends = [(0, [(2, msg.ACK, (5,)), (msg.HOST, msg.HALT, (0,)), (2, msg.ACK, [6, 1])]),
             (1, [(2, msg.TRANSPORT, (1, -1, 1)), (2, msg.ACK, ()), (3, msg.TRANSPORT, (1, -1, 1))])]
    eng.rb[B.IN_HEAD, 4] = eng.rb[B.IN_TAIL, 4] = INBOX - 1      # its ring wraps
    before = [inbox(eng, i) for i in range(6)]
    py = SoaEngine([(validate({"agents": 3, "objectWeight": 2}), s) for s in (1, 2)])
    for a, b in ((py.rb, eng.rb), (py.in_kind, eng.in_kind), (py.in_nf, eng.in_nf),
                 (py.in_f, eng.in_f)):
        a[:] = b
    eng._deliver(sends)
    py._deliver(sends)                               # never stepped: the Python rule
    got = [inbox(eng, i) for i in range(6)]
    assert got == [inbox(py, i) for i in range(6)]
    assert [g[len(b):] for g, b in zip(got, before)] == [
        [(msg.HALT, (0,))], [(msg.ACK, (5,)), (msg.HALT, (0,)), (msg.ACK, (6, 1))],
        [(msg.HALT, (0,))], [], [(msg.TRANSPORT, (1, -1, 1)), (msg.ACK, ())],
        [(msg.TRANSPORT, (1, -1, 1))]]
    for a, b in ((py.rb, eng.rb), (py.in_kind, eng.in_kind), (py.in_nf, eng.in_nf),
                 (py.in_f, eng.in_f)):
        assert np.array_equal(a, b)


def test_a_full_ring_is_refused_whole_with_the_typed_error(stepped):
    eng = stepped
    rings = [a.copy() for a in (eng.rb, eng.in_kind, eng.in_nf, eng.in_f)]
    free = INBOX - (int(eng.rb[B.IN_TAIL, 4]) - int(eng.rb[B.IN_HEAD, 4]))
    with pytest.raises(EngineError, match=f"^run 1: robot 2 has {INBOX} unread messages$"):
        eng._deliver([(0, [(1, msg.ACK, (1,))]),
                      (1, [(2, msg.ACK, (k,)) for k in range(free + 1)])])
    assert all(np.array_equal(a, b) for a, b in
               zip(rings, (eng.rb, eng.in_kind, eng.in_nf, eng.in_f)))
