"""Each behaviour rule of the thesis's robot (Appendix A), one test each."""

from firmware_logic import messages as msg
from firmware_logic.behaviours.thesis import robot as R
from firmware_logic.behaviours.thesis.robot import Robot
from tests.fakehal import FakeHal


def make(model=R.FIREFLY, span=45, defiance=2, node=3, seed=7):
    return Robot(node, seed, model, span, defiance, 100)


def test_firefly_probes_the_four_compass_headings_then_moves_one_patch():
    r, hal = make(), FakeHal()
    r.step(hal)
    assert [c[1] for c in hal.calls("probe")][:4] == [0, 90, 180, 270]
    moves = hal.calls("forward")
    assert len(moves) == 1 and moves[0][2] == 256            # fd 1
    assert r.state == R.SEARCH


def test_firefly_takes_a_new_random_heading_every_step():
    r, hal = make(), FakeHal()
    headings = set()
    for _ in range(50):
        hal.log.clear()
        r.step(hal)
        headings.add(hal.calls("forward")[0][1])
    assert len(headings) > 30


def test_ant_turns_within_vision_span_and_steps_a_quarter_patch():
    r, hal = make(model=R.ANT, span=30), FakeHal()
    for _ in range(200):
        before = r.heading
        hal.log.clear()
        r.step(hal)
        probe_h = hal.calls("probe")[0][1]           # Turn, then LookForObject
        turn = (probe_h - before + 180) % 360 - 180
        assert -30 < turn < 30
        fwd = hal.calls("forward")
        assert fwd and fwd[0][2] == 64 and fwd[0][1] == probe_h   # fd 0.25
    assert len(hal.calls("probe")) == 2


def test_head_carefully_blocked_means_new_heading_and_no_move():
    for blocker in (R.ROBOT, R.CLAIMED, R.WALL):
        r, hal = make(model=R.ANT), FakeHal()
        hal.probe_default = blocker
        before = r.heading
        r.step(hal)
        assert hal.calls("forward") == []
        assert r.heading != before


def test_touching_the_object_claims_it_and_stops():
    r, hal = make(), FakeHal()
    hal.probes = {180: R.OBJECT}
    r.step(hal)
    assert hal.calls("claim") == [("claim", 180)]
    assert hal.calls("forward") == []
    assert r.state == R.GRASP


def test_confirmed_grip_turns_beacon_on_and_reports_the_touch():
    r, hal = make(), FakeHal()
    hal.px, hal.py = 2 * 256, -3 * 256
    hal.probes = {90: R.OBJECT}
    r.step(hal)
    r.step(hal)
    assert r.state == R.HOLD
    assert ("beacon", 1) in hal.log
    touches = [s for s in hal.sent if s[0] == msg.TOUCH]
    assert touches == [(msg.TOUCH, 1, 2, -3, 3, -3, 100)]   # seq, robot, segment, power
    hal.log.clear()
    r.step(hal)
    assert hal.calls("forward") == [] and hal.calls("probe") == []   # stationary


def test_lost_grip_race_resumes_the_search():
    r, hal = make(), FakeHal()
    hal.probes = {0: R.OBJECT}
    r.step(hal)
    hal.held = 0
    r.step(hal)
    assert r.state == R.SEARCH
    assert not [s for s in hal.sent if s[0] == msg.TOUCH]


def test_field_ahead_enters_field_state_and_moves_uphill():
    r, hal = make(model=R.ANT, defiance=2), FakeHal()
    hal.ahead_field = 3
    hal.up = 135
    r.step(hal)
    assert r.state == R.FIELD
    assert hal.calls("forward")[0][1] == 135


def test_in_field_cycle_is_uphill_then_defiance_random_steps():
    r, hal = make(model=R.FIREFLY, defiance=3), FakeHal()
    hal.ahead_field = 5
    hal.up = 45
    r.step(hal)                                  # enters the field, uphill
    uphill_ticks = []
    for t in range(12):
        hal.log.clear()
        r.step(hal)
        if hal.calls("uphill"):
            uphill_ticks.append(t)
            assert hal.calls("forward")[0][1] == 45
            assert [c[1] for c in hal.calls("probe")][:4] == [0, 90, 180, 270]
    assert uphill_ticks == [3, 7, 11]            # 1 uphill + 3 random, repeated


def test_report_is_retransmitted_with_backoff_until_acknowledged():
    r, hal = make(), FakeHal()
    hal.probes = {0: R.OBJECT}
    r.step(hal)
    r.step(hal)
    sent_at = []
    for t in range(40):
        n = len([s for s in hal.sent if s[0] == msg.TOUCH])
        r.step(hal)
        if len([s for s in hal.sent if s[0] == msg.TOUCH]) > n:
            sent_at.append(t)
    gaps = [b - a for a, b in zip(sent_at, sent_at[1:])]
    assert gaps == sorted(gaps) and gaps[-1] > gaps[0]      # backing off
    hal.inbox.append((msg.ACK, (1,)))
    n = len(hal.sent)
    for _ in range(100):
        r.step(hal)
    assert not [s for s in hal.sent[n:] if s[0] == msg.TOUCH]


def test_first_retransmission_is_retx_first_ticks_after_the_send():
    """The timer was set and decremented in the same tick, so the
    first retry came after 3 ticks, not the documented RETX_FIRST (4)."""
    r, hal = make(), FakeHal()
    hal.probes = {0: R.OBJECT}
    r.step(hal)                                  # claims
    sent_at = []
    for t in range(1, 300):                      # tick 1 confirms the grip and sends
        n = len([s for s in hal.sent if s[0] == msg.TOUCH])
        r.step(hal)
        if len([s for s in hal.sent if s[0] == msg.TOUCH]) > n:
            sent_at.append(t)
    gaps = [b - a for a, b in zip(sent_at, sent_at[1:])]
    assert sent_at[0] == 1
    assert gaps[:7] == [R.RETX_FIRST, 8, 16, 32, R.RETX_MAX, R.RETX_MAX, R.RETX_MAX]


def test_transport_before_the_touch_is_acknowledged_is_ignored():
    """The host ACKs a touch before it commands the carrier, so a
    TRANSPORT before that ACK is not the host's (or not yet converged)."""
    r, hal = make(), FakeHal()
    hal.probes = {0: R.OBJECT}
    r.step(hal)
    r.step(hal)
    hal.inbox.append((msg.TRANSPORT, (1, -1, -1)))
    r.step(hal)
    assert r.state == R.HOLD and hal.calls("carry") == []
    hal.inbox += [(msg.ACK, (1,)), (msg.TRANSPORT, (1, -1, -1))]
    r.step(hal)
    assert r.state == R.CARRY and hal.calls("carry") == [("carry", -1, -1)]


def test_a_touch_ack_acknowledges_the_hello_too():
    # the host sends one ACK per node per tick; a touch's wins over the HELLO's
    r, hal = make(), FakeHal()
    hal.probes = {0: R.OBJECT}
    r.step(hal)
    r.step(hal)
    hal.inbox.append((msg.ACK, (1,)))
    n = len(hal.sent)
    for _ in range(20):
        r.step(hal)
    assert r.pending == 0 and not [s for s in hal.sent[n:] if s[0] in (msg.HELLO, msg.TOUCH)]


def test_transport_command_moves_a_holder_and_halt_stops_it():
    r, hal = make(), FakeHal()
    hal.probes = {0: R.OBJECT}
    r.step(hal)
    r.step(hal)
    hal.inbox += [(msg.ACK, (1,)), (msg.TRANSPORT, (1, -1, -1))]
    r.step(hal)
    assert r.state == R.CARRY and hal.calls("carry") == [("carry", -1, -1)]
    hal.inbox.append((msg.TRANSPORT, (1, -1, -1)))      # duplicate: ignored
    r.step(hal)
    assert len(hal.calls("carry")) == 1
    hal.inbox.append((msg.HALT, (0,)))
    r.step(hal)
    assert r.state == R.HALT and ("beacon", 0) in hal.log


def test_transport_is_ignored_by_robots_not_holding():
    r, hal = make(), FakeHal()
    hal.inbox.append((msg.TRANSPORT, (1, -1, -1)))
    r.step(hal)
    assert r.state == R.SEARCH and hal.calls("carry") == []


def test_hello_repeats_until_acknowledged():
    r, hal = make(), FakeHal()
    for _ in range(9):
        r.step(hal)
    assert len([s for s in hal.sent if s[0] == msg.HELLO]) == 3
    hal.inbox.append((msg.ACK, (0,)))
    n = len(hal.sent)
    for _ in range(20):
        r.step(hal)
    assert not [s for s in hal.sent[n:] if s[0] == msg.HELLO]
