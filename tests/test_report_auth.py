"""Authenticated and plausible reports: the host's word can be trusted only if what it is told
is. Robot reports are sealed too (bridge/links/secoc.py, "robot reports"):
with keys, a TOUCH or HEARTBEAT that does not verify under its robot's key,
bound to the last host command that robot took, never reaches the
coordinator; and the coordinator checks what it is told against its own
model (a TOUCH on a segment another robot holds, a leader pose that does not
follow the commanded step), keys or not. Each attack below made the host
declare delivery, or count forged touches, on the code before."""

from __future__ import annotations

import pytest

from bridge.host.process import HostProcess
from bridge.host.swarm import swarm_engine
from bridge.host.transport import CanTransport
from bridge.links import open_bus, secoc
from bridge.links.canlink import private_channel
from bridge.links.codec import BadFrames, encode
from firmware_logic import messages as msg
from sim_backend import scenario

KEYS = {n: bytes([n, 3]) * 8 for n in range(1, 21)}
ALIEN = {n: bytes([0x5A]) * 16 for n in range(1, 21)}


def _mission(keys, strike, max_ticks=6000):
    """The default mission over a virtual CAN bus on a simulated clock
    (hil_tests' Lockstep); `strike(host, bus)` runs after every robot tick
    (its frames are on the bus: the forger has the last word before the
    host's tick) with a forger's handle on the bus."""
    from hil_tests.test_can_auth import Draining
    from hil_tests.test_can_mission import TICK, SimClock
    sc = scenario.load("default")
    url = f"virtual://{private_channel('reports')}"
    clock = SimClock()
    with open_bus(url) as rb, open_bus(url) as fb:
        engine = swarm_engine(sc, 1, rb, keys=keys)
        sealer = secoc.Sealer(keys) if keys is not None else None
        host = HostProcess(Draining(CanTransport(open_bus(url), sealer=sealer), engine, clock),
                           sc.weight_centi, sc.homeX, sc.homeY, tick_seconds=TICK)
        step = engine.step

        def forged_step():
            step()
            strike(host, fb)
        engine.step = forged_step
        with host.transport:
            out = host.run(max_ticks=max_ticks, clock=clock)
    return sc, host, out, engine


class HomeHeartbeat:
    """Once the transport is under way: one HEARTBEAT with the leader's id,
    carrying, at home, reporting the step the host awaits (plain, or sealed
    with another swarm's keys, which is all a forger without the key file
    has). On the code before, the host declared delivery at once, the object
    still far from home, and halted the swarm."""

    def __init__(self, sealed_with=None):
        self.sealed_with = sealed_with
        self.done_at = None
        self.delivered_then = None

    def __call__(self, host, bus):
        c = host.coord
        if self.done_at is None and c.step >= 2 and c.leader:
            sc = scenario.load("default")
            fields = (4, sc.homeX * 256, sc.homeY * 256, 0, c.step)
            if self.sealed_with is None:
                frame = encode(c.leader, msg.HEARTBEAT, fields)
            else:
                alien = secoc.Opener(self.sealed_with, BadFrames("alien"))
                alien.h[c.leader] = host.transport.inner.sealer.fv[c.leader] \
                    if host.transport.inner.sealer else 1
                frame = alien.seal_report(c.leader, msg.HEARTBEAT, fields)
            bus.send(frame)
            self.done_at = host.tick
            self.far = c._home_d2(0, 0)
        elif self.done_at is not None and self.delivered_then is None \
                and host.tick > self.done_at + 1:
            self.delivered_then = c.delivered_tick >= 0


@pytest.mark.parametrize("keys, sealed_with, fault", [
    (KEYS, None, secoc.REPORT_BAD_MAC),     # a plain HEARTBEAT has 8 bytes too
    (KEYS, ALIEN, secoc.REPORT_BAD_MAC),
    (None, None, None),
])
def test_a_spoofed_leader_heartbeat_at_home_does_not_deliver(keys, sealed_with, fault):
    strike = HomeHeartbeat(sealed_with)
    sc, host, out, engine = _mission(keys, strike)
    assert strike.done_at is not None and strike.far > 4 * 4, strike.far   # far from home
    assert strike.delivered_then is False
    # the mission goes on and delivers for real: the host's model has the object home
    assert out["outcome"] == "delivered", out
    assert host.coord._home_reached()
    if fault is not None:
        assert out["bad_frames"].get(fault) == 1, out["bad_frames"]
    else:
        # without keys the forged frame reaches the coordinator, which finds
        # that the leader's pose does not follow the step it commanded
        from firmware_logic.behaviours.thesis import coordinator as tc
        assert out["rejected"].get(tc.LEADER_JUMP) == 1, out["rejected"]


def _keyed_pair():
    url = f"virtual://{private_channel('touch')}"
    rb, hb = open_bus(url), open_bus(url)
    sealer = secoc.Sealer(KEYS)
    host = CanTransport(hb, sealer=sealer)
    robots = secoc.Opener(KEYS, BadFrames("robots"))
    return rb, host, sealer, robots


def _poll_all(host, n_frames):
    got = []
    while host.frames_in < n_frames:
        got += host.poll(1.0)
    return got


def test_forged_seq_1_touches_for_every_node_are_dropped_with_keys():
    """On the code before, a plain TOUCH seq 1 with a plausible segment for
    every announced node was accepted by a keyed host (TOUCH was not
    authenticated). Now plain ones, ones sealed with another key and replays
    of genuine ones are dropped and counted; a genuine one passes, with the
    power of its node's HELLO."""
    rb, host, sealer, robots = _keyed_pair()
    with rb, host:
        sent = 0
        for n in range(1, 6):
            rb.send(robots.hello(encode(n, msg.HELLO, (1, 100, 1))))
            sent += 1
        assert [m[1] for m in _poll_all(host, sent)] == [msg.HELLO] * 5
        for n in range(1, 6):
            host.send(n, msg.ACK, (0,))                  # the robot takes its HELLO's ACK
            assert robots.open(sealer_frame(rb)) is not None
        touch = (1, 2, 2, 3, 2, 100)
        alien = secoc.Opener(ALIEN, BadFrames("alien"))
        for n in range(1, 6):
            alien.h[n] = sealer.fv[n]
            rb.send(encode(n, msg.TOUCH, touch))                 # plain
            rb.send(alien.seal_report(n, msg.TOUCH, touch))      # another key
        sent += 10
        assert _poll_all(host, sent) == []
        bad = host.bad_frames()
        assert bad[secoc.REPORT_PLAIN] == 5 and bad[secoc.REPORT_BAD_MAC] == 5
        genuine = robots.seal_report(3, msg.TOUCH, touch)
        rb.send(genuine)
        rb.send(genuine)                                         # duplicated
        rb.send(robots.seal_report(3, msg.TOUCH, touch))         # the retransmission
        rb.send(genuine)                                         # replayed
        sent += 4
        assert _poll_all(host, sent) == [(3, msg.TOUCH, touch)] * 2
        # a duplicate of the last report is counted as such; a replay of an
        # older one reads as the next report under that H: its MAC fails
        bad = host.bad_frames()
        assert bad[secoc.REPORT_DUPLICATE] == 1 and bad[secoc.REPORT_BAD_MAC] == 6


def sealer_frame(bus):
    """The host's last command, as the robots' side reads it off the bus."""
    f = bus.recv(1.0)
    assert f is not None
    return f


@pytest.mark.parametrize("kind, fields", [
    (msg.TOUCH, (7, -3, 4, -2, 5, 250)),
    (msg.TOUCH, (255, 10, -10, 9, -11, 250)),
    (msg.HEARTBEAT, (4, 5 * 256, -7 * 256, 0, 200)),
])
def test_a_sealed_report_opens_to_the_plain_fields(kind, fields):
    robots = secoc.Opener(KEYS, BadFrames("robots"))
    sealer = secoc.Sealer(KEYS)
    (cmd,) = sealer.seal(encode(4, msg.ACK, (0,)))
    assert robots.open(cmd) is not None
    sealer.hellos[4] = (1, 250, 1)
    frame = robots.seal_report(4, kind, fields)
    assert frame.dlc == 8
    assert sealer.open_report(frame, 4) == fields


def test_a_robot_holds_its_reports_back_until_it_took_a_host_command():
    robots = secoc.Opener(KEYS, BadFrames("robots"))
    assert robots.seal_report(2, msg.HEARTBEAT, (0, 0, 0, 0, 0)) is None
    assert robots.held_back == 1


def test_a_report_sealed_under_an_earlier_hosts_counters_is_not_taken_by_a_new_mission(
        tmp_path):
    """A report captured in an earlier run carries that run's H: a host that
    did not resume takes only counters it sealed itself (its freshness file
    starts it above every counter it used before)."""
    store = tmp_path / "k.toml.fv.json"
    old = secoc.Sealer(KEYS, secoc.FreshnessStore(store))
    robots = secoc.Opener(KEYS, BadFrames("robots"))
    assert robots.open(old.seal(encode(2, msg.ACK, (0,)))[0]) is not None
    captured = robots.seal_report(2, msg.HEARTBEAT, (0, 256, 256, 0, 0))
    old.hellos[2] = (1, 100, 1)
    assert old.open_report(captured, 2) is not None
    new = secoc.Sealer(KEYS, secoc.FreshnessStore(store))
    new.bad = BadFrames("host")
    new.seal(encode(2, msg.ACK, (0,)))
    assert new.open_report(captured, 2) is None
    assert new.bad.counts == {secoc.REPORT_BAD_MAC: 1}


def test_the_one_block_cmac_is_the_cmac():
    for key in (KEYS[1], ALIEN[1]):
        c = secoc.cmac1(key)
        for n in (0, 1, 10, 14, 15):
            m = bytes(range(n))
            assert c.mac(m) == secoc.reference_mac(key, m)
        assert c.many([c.block(b"ab"), c.block(b"")]) == [
            secoc.reference_mac(key, b"ab"), secoc.reference_mac(key, b"")]


def test_a_behaviours_own_report_is_sealed_in_whole_patches():
    """aggregate's LEAVE (seq, x, y in Q8: 5 bytes) is sealed with x and y in
    whole patches (3 bytes)."""
    from sim_backend import registry
    b = registry.load("aggregate").activate()
    try:
        from firmware_logic.behaviours.aggregate.spec import LEAVE
        robots = secoc.Opener(KEYS, BadFrames("robots"))
        sealer = secoc.Sealer(KEYS)
        assert robots.open(sealer.seal(encode(5, msg.ACK, (0,)))[0]) is not None
        frame = robots.seal_report(5, LEAVE, (3, 3 * 256 + 100, -2 * 256 - 20))
        assert sealer.open_report(frame, 5) == (3, 3 * 256, -2 * 256)
    finally:
        registry.load("thesis").activate()
    assert b.name == "aggregate"


def test_a_touch_on_a_segment_another_robot_holds_is_rejected_and_journalled(tmp_path):
    """Keys or not: a robot holds a segment alone (the world's claim has one
    owner), so a second node's TOUCH of it is a forgery or a fault; it is
    refused, never acted on, and kept in the journal's `rejected` table as
    evidence (never replayed)."""
    from bridge.host.journal import Journal
    from firmware_logic.behaviours.thesis import coordinator as tc
    from tests.test_journal import FakeTransport
    with Journal(tmp_path / "j.sqlite") as j:
        h = HostProcess(FakeTransport(), weight=500, journal=j)
        h.handle([(4, msg.HELLO, (1, 100, 1)), (5, msg.HELLO, (1, 100, 1))])
        h.step()
        h.handle([(4, msg.TOUCH, (1, 2, 2, 3, 2, 100)), (5, msg.TOUCH, (1, 4, 2, 3, 2, 100))])
        h.step()
        assert [t.node for t in h.coord.touches] == [4] and h.coord.power == 100
        assert h.coord.rejected == {tc.CLAIMED: 1}
        assert j.rejected() == [(5, msg.TOUCH, 1, tc.CLAIMED, (1, 4, 2, 3, 2, 100))]
        assert [r.node for r in j.reports(msg.TOUCH)] == [4]


def test_a_resumed_host_takes_reports_sealed_under_its_predecessors_counters(tmp_path):
    """The robots ran on while the host was restarted with --resume: their
    reports are bound to the last command of the old host. The resumed host
    (its freshness file starts it above every counter the old one used)
    looks for H below its first counter once per node, and takes a TOUCH's
    power from the journal's HELLO (`nodes`, the coordinator's record)."""
    store = tmp_path / "k.toml.fv.json"
    old = secoc.Sealer(KEYS, secoc.FreshnessStore(store))
    robots = secoc.Opener(KEYS, BadFrames("robots"))
    for seq in range(1, 40):
        assert robots.open(old.seal(encode(6, msg.ACK, (seq,)))[0]) is not None
    touch = (1, 2, 2, 3, 2, 100)
    new = secoc.Sealer(KEYS, secoc.FreshnessStore(store))
    new.bad = BadFrames("host")
    new.nodes = {6: (1, 100)}
    assert new.open_report(robots.seal_report(6, msg.TOUCH, touch), 6) is None   # not resumed
    new.resumed = True
    assert new.open_report(robots.seal_report(6, msg.TOUCH, touch), 6) == touch
    assert new.open_report(robots.seal_report(6, msg.TOUCH, touch), 6) == touch


def test_a_keyed_aggregation_mission_delivers_with_every_report_sealed():
    """Another behaviour's reports (aggregate: TOUCH as a stop, LEAVE, the
    HEARTBEAT's state) are sealed and opened the same way: the mission ends
    with its quorum and the host drops none of the robots' frames."""
    from hil_tests.test_can_auth import Draining
    from hil_tests.test_can_mission import TICK, SimClock
    from bridge.host.swarm import swarm_summary
    sc = scenario.load("default").replace(behaviour="aggregate", quorum=80)
    url = f"virtual://{private_channel('agg')}"
    clock = SimClock()
    with open_bus(url) as rb:
        engine = swarm_engine(sc, 1, rb, keys=KEYS)
        host = HostProcess(Draining(CanTransport(open_bus(url), sealer=secoc.Sealer(KEYS)),
                                    engine, clock), 0, behaviour="aggregate", scenario=sc,
                           tick_seconds=TICK)
        with host.transport:
            out = host.run(max_ticks=6000, clock=clock)
        r = swarm_summary(engine)
    assert out["outcome"] == "delivered", out
    assert not [k for k in out["bad_frames"] if "MAC" in k or "report" in k], out["bad_frames"]
    assert r["bad_frames"] == {} and r["halted"]
    assert {tuple(t) for t in out["touches"]} <= {tuple(t) for t in r["reported"]}
