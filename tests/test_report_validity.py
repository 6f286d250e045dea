"""The host is never fooled by what a robot (or anything on the
bus) reports. A report is checked before it is journalled; one that fails is
counted by reason, logged once per reason, not journalled and not ACKed."""

from __future__ import annotations

import logging
from pathlib import Path

import pytest

from bridge.host.journal import Journal
from bridge.host.process import HostProcess
from firmware_logic import messages as msg
from sim_backend import registry
from firmware_logic.behaviours.thesis import coordinator as co
from firmware_logic.behaviours.thesis.coordinator import Coordinator, Touch
from sim_backend.engine import Engine
from sim_backend.scenario import Scenario, load as load_scenario
from tests.test_journal import FakeTransport

BAR = [(3, 3), (4, 3), (5, 3), (6, 3)]        # an object the host knows


def hello(c: Coordinator, node: int, power: int = 100, model: int = 1) -> None:
    c.on_message(node, msg.HELLO, (model, power, 1), 1)


def touch(c: Coordinator, node: int, seq: int, seg: tuple[int, int],
          robot: tuple[int, int] | None = None, power: int = 100, tick: int = 5) -> None:
    rx, ry = robot if robot else (seg[0], seg[1] - 1)
    c.on_message(node, msg.TOUCH, (seq, rx, ry, seg[0], seg[1], power), tick)


def coordinator(**kw) -> tuple[Coordinator, list[Touch]]:
    journalled: list[Touch] = []     # the TOUCH reports journalled, as the robot sent them

    def journal(node: int, kind: int, f: tuple, tick: int) -> None:
        if kind == msg.TOUCH:
            journalled.append(Touch(node, *f, tick))
    c = Coordinator(300, world_size=18, journal=journal, **kw)
    for n in (1, 2, 3):
        hello(c, n)
    c.tick(1)
    return c, journalled


@pytest.mark.parametrize("seg,robot,power,reason", [
    ((120, 120), (120, 119), 100, co.OUTSIDE),        # accepted before
    ((19, 0), (18, 0), 100, co.OUTSIDE),              # just outside a 18-patch arena
    ((5, 5), (5, 5), 100, co.NOT_ADJACENT),           # robot on its segment
    ((5, 5), (5, 3), 100, co.NOT_ADJACENT),
    ((-14, -14), (-13, -14), 100, co.AT_HOME),         # "delivered" at once
    ((5, 5), None, 65535, co.WRONG_POWER),            # converged at once
    ((5, 5), None, 99, co.WRONG_POWER),
])
def test_an_invalid_touch_is_rejected_before_the_journal(seg, robot, power, reason):
    c, journalled = coordinator()
    touch(c, 1, 1, seg, robot, power)
    out = c.tick(5) + c.tick(6)
    assert c.rejected == {reason: 1}
    assert journalled == [] and c.touches == [] and c.power == 0
    assert out == [] and c.converged_tick == -1 and c.delivered_tick == -1


def test_a_touch_from_an_unannounced_node_is_rejected_until_its_hello():
    c, journalled = coordinator()
    touch(c, 9, 1, (5, 5))
    assert c.rejected == {co.UNANNOUNCED_TOUCH: 1} and journalled == []
    hello(c, 9)
    touch(c, 9, 1, (5, 5))        # the robot's retransmission after its HELLO
    assert [t.node for t in journalled] == [9]
    assert c.tick(6) == [(9, msg.ACK, (1,))]


def test_when_the_host_knows_the_object_only_its_cells_count():
    c, journalled = coordinator(cells=BAR)
    touch(c, 1, 1, (0, 0))                       # plausible, but not the object
    touch(c, 2, 1, (4, 3), robot=(4, 2))
    assert c.rejected == {co.NOT_OBJECT: 1}
    assert [(t.node, t.sx, t.sy) for t in journalled] == [(2, 4, 3)]


def test_the_object_cells_move_with_the_transport():
    c, _ = coordinator(cells=BAR)
    c.moved_x, c.moved_y = -2, -1                # the object was carried (-2, -1)
    touch(c, 1, 1, (4, 3), robot=(4, 2))          # where the object was
    touch(c, 2, 1, (2, 2), robot=(2, 1))          # where it is: cell (4, 3) now
    assert c.rejected == {co.NOT_OBJECT: 1}
    assert [(t.node, t.sx, t.sy) for t in c.touches] == [(2, 4, 3)]
    # its retransmission, sent as it was first sent, is a duplicate, even after
    # the object moved on
    c.moved_x, c.moved_y = -5, -4
    touch(c, 2, 1, (2, 2), robot=(2, 1))
    assert c.duplicates == 1 and c.rejected == {co.NOT_OBJECT: 1}
    assert c.tick(7) == [(2, msg.ACK, (1,))]


def test_a_second_touch_from_a_node_is_rejected_not_counted_twice():
    c, journalled = coordinator()
    touch(c, 1, 1, (5, 5))
    touch(c, 1, 2, (6, 5))                        # counted twice before
    touch(c, 1, 7, (5, 5))                        # a new seq for the same segment
    assert c.power == 100 and len(journalled) == 1 and c.duplicates == 0
    assert c.rejected == {co.SECOND_TOUCH: 2}
    assert c.tick(6) == [(1, msg.ACK, (1,))]


def test_a_forged_seq_never_turns_the_real_touch_into_a_duplicate():
    """A forged seq-1 TOUCH for every node before their real ones made
    the real ones 'duplicates'. A forgery that is not on the object is
    rejected; the real touches then count."""
    c, journalled = coordinator(cells=BAR)
    for n in (1, 2, 3):
        touch(c, n, 1, (0, 0))                   # forged: plausible, not the object
    for n, x in ((1, 3), (2, 4), (3, 5)):
        touch(c, n, 1, (x, 3), robot=(x, 2))     # the real ones
    assert c.duplicates == 0 and c.rejected == {co.NOT_OBJECT: 3}
    assert [t.node for t in journalled] == [1, 2, 3] and c.power == 300
    # a forgery about the real segment but a different robot patch is no duplicate
    # of the real touch either: it is a second report, rejected
    touch(c, 1, 1, (3, 3), robot=(2, 2))
    assert c.duplicates == 0 and c.rejected[co.SECOND_TOUCH] == 1


def test_a_hello_that_changes_model_or_power_is_rejected():
    c, _ = coordinator()
    hello(c, 1, power=65535)
    hello(c, 1, model=2)
    hello(c, 4, model=9)                         # not a model
    hello(c, 5, power=0)
    assert c.nodes[1] == (1, 100) and 4 not in c.nodes and 5 not in c.nodes
    assert c.rejected == {co.CHANGED_HELLO: 2, co.BAD_HELLO: 2}
    assert c.tick(2) == []                        # none of them ACKed
    hello(c, 1)                                  # the same HELLO again: ACKed
    assert c.tick(3) == [(1, msg.ACK, (0,))]


def test_memory_journal_and_a_resumed_host_agree_on_a_changed_hello(tmp_path: Path):
    p = tmp_path / "j.sqlite"
    with Journal(p) as j:
        h = HostProcess(FakeTransport(), weight=500, journal=j)
        h.handle([(4, msg.HELLO, (1, 100, 1))])
        h.step()
        h.handle([(4, msg.HELLO, (2, 600, 1))])   # memory took it, journal not
        h.step()
        assert h.coord.nodes == j.nodes() == {4: (1, 100)}
        assert h.summary()["rejected"] == {co.CHANGED_HELLO: 1}
    with Journal(p) as j:
        r = HostProcess(FakeTransport(), weight=500, journal=j)
        r.resume(j)
        assert r.coord.nodes == {4: (1, 100)}
        r.handle([(4, msg.HELLO, (2, 600, 1)), (4, msg.TOUCH, (1, 2, 2, 3, 2, 600))])
        r.step()
        assert r.coord.nodes == j.nodes() == {4: (1, 100)} and j.reports(msg.TOUCH) == []
        assert r.coord.rejected == {co.CHANGED_HELLO: 1, co.WRONG_POWER: 1}


def test_rejections_are_logged_once_per_reason_and_never_journalled(tmp_path: Path, caplog):
    with Journal(tmp_path / "j.sqlite") as j, \
            caplog.at_level(logging.WARNING, logger="bridge.host.process"):
        h = HostProcess(FakeTransport(), weight=500, journal=j, world_size=18)
        h.handle([(4, msg.HELLO, (1, 100, 1))])
        h.step()
        for _ in range(3):
            h.handle([(4, msg.TOUCH, (1, 120, 119, 120, 120, 100)),
                      (4, msg.TOUCH, (1, 2, 2, 3, 2, 65535))])
        h.step()
        assert j.reports(msg.TOUCH) == [] and h.coord.power == 0
        assert h.summary()["rejected"] == {co.OUTSIDE: 3, co.WRONG_POWER: 3}
        lines = [r.getMessage() for r in caplog.records if "rejected" in r.getMessage()]
        assert len(lines) == 2


def test_ten_thousand_fold_hellos_make_one_ack():
    """10^5 HELLOs made 10^5 ACKs in one tick. At most one ACK per
    node per tick, whatever arrives."""
    tr = FakeTransport()
    h = HostProcess(tr, weight=500)
    h.handle([(4, msg.HELLO, (1, 100, 1))] * 100_000 + [(5, msg.HELLO, (1, 100, 1))])
    h.step()
    assert tr.sent == [(4, msg.ACK, (0,)), (5, msg.ACK, (0,))]
    tr.sent.clear()
    # a touch and a flood of its retransmissions in one tick: one ACK, its seq
    h.handle([(4, msg.HELLO, (1, 100, 1)), (4, msg.TOUCH, (1, 2, 2, 3, 2, 100))]
             + [(4, msg.TOUCH, (1, 2, 2, 3, 2, 100))] * 100_000
             + [(4, msg.HELLO, (1, 100, 1))])
    h.step()
    assert tr.sent == [(4, msg.ACK, (1,))]


@pytest.mark.parametrize("scenario,seed", [("default", 1), ("default", 2), ("ant", 3)])
def test_real_missions_pass_the_checks_with_the_object_known(scenario: str, seed: int):
    """The rules never reject what a simulated robot really reports, with the
    object's cells given to the coordinator as a simulation can."""
    sc: Scenario = load_scenario(scenario)
    plain = Engine(sc, seed).run()
    e = Engine(sc, seed)
    e.coordinator = registry.load(sc.behaviour).coordinator(sc, cells=e.world.object_cells)
    r = e.run()
    assert r.delivered and r.coordinator.rejected == {}
    assert r.summary() == plain.summary()


def test_a_poisoned_journal_never_crashes_or_fools_a_resumed_host(tmp_path: Path):
    """The home touch was journalled first, so every --resume crashed
    again. A journal an older host wrote with such touches in it (at home, off
    the arena, with a forged power) is resumed without them."""
    p = tmp_path / "old.sqlite"
    with Journal(p) as j:
        for node, power, touch, tick in (
                (7, 600, (1, -15, -16, -15, -15, 600), 2),      # at home
                (8, 100, (1, 120, 119, 120, 120, 100), 3),      # outside
                (9, 100, (1, 2, 2, 3, 2, 65535), 4),            # power
                (10, 100, (1, 2, 3, 3, 3, 100), 5)):            # a good one
            j.add_report(node, msg.HELLO, (1, power, 1), tick)
            j.add_report(node, msg.TOUCH, touch, tick)
    with Journal(p) as j:
        h = HostProcess(FakeTransport(), weight=600, journal=j, world_size=18)
        assert h.resume(j) == 1
        for _ in range(5):
            h.step()
        s = h.summary()
        assert s["touches"] == [[10, 1]] and s["power"] == 1.0 and not s["delivered"]
        assert s["converged_tick"] is None
        assert s["rejected"] == {co.AT_HOME: 1, co.OUTSIDE: 1, co.WRONG_POWER: 1}
