"""SoaEngine._deliver: a tick's commands into the robots' inbox rings, each
robot's in the order sent (an engine built, not stepped: nothing compiles)."""

import pytest

from firmware_logic import messages as msg
from sim_backend.batch import body as B
from sim_backend.batch.soa import INBOX, SoaEngine
from sim_backend.errors import EngineError
from sim_backend.scenario import validate


def inbox(eng, i):
    """Robot i's unread messages, oldest first: (kind, fields)."""
    head, tail = int(eng.rb[B.IN_HEAD, i]), int(eng.rb[B.IN_TAIL, i])
    out = []
    for pos in range(head, tail):
        s = pos % INBOX
        nf = int(eng.in_nf[i, s])
        out.append((int(eng.in_kind[i, s]), tuple(eng.in_f[i, s, :nf].tolist())))
    return out


def test_commands_reach_their_robots_in_order_and_a_full_ring_is_an_error():
    sc = validate({"agents": 3, "objectWeight": 2})
    eng = SoaEngine([(sc, 1), (sc, 2)])
    eng.rb[B.IN_HEAD, 4] = eng.rb[B.IN_TAIL, 4] = INBOX - 1      # robot 2 of run 1 wraps
    eng._deliver([(0, [(2, msg.ACK, (5,)), (msg.HOST, msg.HALT, (0,)), (2, msg.ACK, (6,))]),
                  (1, [(2, msg.TRANSPORT, (1, -1, 1)), (2, msg.ACK, ())])])
    assert inbox(eng, 0) == [(msg.HALT, (0,))]
    assert inbox(eng, 1) == [(msg.ACK, (5,)), (msg.HALT, (0,)), (msg.ACK, (6,))]
    assert inbox(eng, 3) == []
    assert inbox(eng, 4) == [(msg.TRANSPORT, (1, -1, 1)), (msg.ACK, ())]
    with pytest.raises(EngineError, match="not one of its 3 robots"):
        eng._deliver([(1, [(4, msg.ACK, (1,))])])
    with pytest.raises(EngineError, match=f"run 1: robot 1 has {INBOX} unread"):
        eng._deliver([(1, [(1, msg.ACK, (k,)) for k in range(INBOX + 1)])])
    assert inbox(eng, 3) == []                 # refused whole: nothing written


def test_shared_and_list_fields_each_reach_their_robot_with_their_own_count():
    """One fields object sent to several robots, equal fields of two kinds,
    and fields given as a list: each robot's row holds its own kind, count
    and fields."""
    sc = validate({"agents": 3, "objectWeight": 2})
    eng = SoaEngine([(sc, 1), (sc, 2)])
    step = (4, 1, -1)
    eng._deliver([(0, [(1, msg.TRANSPORT, step), (3, msg.TRANSPORT, step), (2, msg.ACK, (4,))]),
                  (1, [(1, msg.ACK, [4]), (2, msg.HALT, (4,)), (3, msg.ACK, [1, 2])])])
    assert [inbox(eng, i) for i in range(6)] == [
        [(msg.TRANSPORT, step)], [(msg.ACK, (4,))], [(msg.TRANSPORT, step)],
        [(msg.ACK, (4,))], [(msg.HALT, (4,))], [(msg.ACK, (1, 2))]]
    with pytest.raises(EngineError, match="sent 7 fields"):
        eng._deliver([(0, [(1, msg.ACK, [0] * 7)])])


def test_a_batch_keeps_its_heap_from_the_collector_while_a_step_runs_only():
    """What is alive when a tick steps is frozen (gc.freeze) for that step
    and handed back to the collector after it, even when the step fails;
    between steps nothing is frozen, so an engine dropped unfinished inside
    a reference cycle is collected."""
    import gc
    import weakref

    from sim_backend.batch.soa import _STEPPING
    sc = validate({"agents": 3, "objectWeight": 2})
    a = SoaEngine([(sc, 1)])
    seen: list[int] = []
    inner = [a._tick]

    def watched(t: int) -> None:
        seen.append(gc.get_freeze_count())
        inner[0](t)
    a._tick = watched                     # the engine now sits in a cycle
    a.step()                              # the first tick (compiled or loaded)
    a.step()
    assert len(seen) == 1 and seen[0] > 0            # frozen while the second tick ran
    assert _STEPPING == [0] and gc.get_freeze_count() == 0

    def failing(t: int) -> None:
        raise RuntimeError("tick failed")
    a._tick = failing
    with pytest.raises(RuntimeError, match="tick failed"):
        a.step()
    assert _STEPPING == [0] and gc.get_freeze_count() == 0
    gone = weakref.ref(a)
    inner.clear()
    del a, watched, failing
    gc.collect()
    assert gone() is None and gc.isenabled()


def test_one_fields_object_under_two_kinds_and_runs_keeps_each_kind():
    """_deliver reuses the last message's row while the fields object and
    kind stay the same: a change of kind alone, or the same object again
    after another, gets its own row."""
    sc = validate({"agents": 3, "objectWeight": 2})
    eng = SoaEngine([(sc, 1), (sc, 2)])
    f = (7,)
    eng._deliver([(0, [(1, msg.ACK, f), (1, msg.HALT, f), (2, msg.HALT, f)]),
                  (1, [(1, msg.ACK, (8,)), (1, msg.ACK, f), (2, msg.HALT, f)])])
    assert [inbox(eng, i) for i in range(5)] == [
        [(msg.ACK, (7,)), (msg.HALT, (7,))], [(msg.HALT, (7,))], [],
        [(msg.ACK, (8,)), (msg.ACK, (7,))], [(msg.HALT, (7,))]]
