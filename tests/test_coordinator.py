"""The host coordinator: touches, power, leader, transport, arrival."""

from firmware_logic import messages as msg
from firmware_logic.behaviours.thesis.coordinator import Coordinator


def hello(c, node, power=100, tick=1):
    c.on_message(node, msg.HELLO, (1, power, 1), tick)


def touch(c, node, seq, seg, tick, power=100, robot=None):
    rx, ry = robot if robot else (seg[0], seg[1] - 1)
    c.on_message(node, msg.TOUCH, (seq, rx, ry, seg[0], seg[1], power), tick)


def test_hello_is_acknowledged_and_unannounced_touches_are_rejected():
    c = Coordinator(300)
    touch(c, 4, 1, (5, 5), 2)
    assert c.touches == [] and c.rejected == {"touch from unannounced node": 1}
    hello(c, 4)
    assert c.tick(3) == [(4, msg.ACK, (0,))]


def test_duplicates_are_acknowledged_but_counted_once():
    c = Coordinator(300)
    hello(c, 2)
    c.tick(1)
    touch(c, 2, 1, (5, 5), 10)
    touch(c, 2, 1, (5, 5), 11)
    assert c.power == 100 and len(c.touches) == 1 and c.duplicates == 1
    assert c.tick(11) == [(2, msg.ACK, (1,))]        # one ACK per node per tick
    touch(c, 2, 1, (5, 5), 12)
    assert c.tick(12) == [(2, msg.ACK, (1,))] and c.duplicates == 2


def test_journal_is_written_before_the_ack():
    order = []
    c = Coordinator(300, journal=lambda node, kind, f, tick: order.append(
        ("journal", node, kind, f[0])))
    hello(c, 2)
    order += [("sent",) + cmd[:2] for cmd in c.tick(1)]
    touch(c, 2, 1, (5, 5), 10)
    order += [("sent",) + cmd[:2] for cmd in c.tick(10)]
    assert order == [("journal", 2, msg.HELLO, 1), ("sent", 2, msg.ACK),
                     ("journal", 2, msg.TOUCH, 1), ("sent", 2, msg.ACK)]


def test_leader_is_first_finder_and_transport_commands_only_holders():
    c = Coordinator(200)
    for n in (1, 2, 3):
        hello(c, n)
    c.tick(1)
    touch(c, 3, 1, (5, 5), 10)
    assert c.tick(10)[0] == (3, msg.ACK, (1,)) and c.converged_tick == -1
    touch(c, 1, 1, (6, 5), 12)
    cmds = c.tick(12)
    assert c.leader == 3 and c.found_tick == 10 and c.converged_tick == 12
    transports = [cmd for cmd in cmds if cmd[1] == msg.TRANSPORT]
    assert sorted(cmd[0] for cmd in transports) == [1, 3]          # not robot 2
    assert transports[0][2] == (1, -1, -1)                          # toward (-15, -15)


def drive_home(c, pose, ticks=range(6, 80)):
    """Node 1, the leader, executes every step it is given until delivery;
    its pose then."""
    for t in ticks:
        step = c.step
        # the leader reports the pose after executing the current step
        pose = [pose[0] + c.dx, pose[1] + c.dy]
        c.on_message(1, msg.HEARTBEAT, (4, pose[0] * 256, pose[1] * 256, 0, step), t)
        c.tick(t)
        if c.delivered_tick >= 0:
            break
    return pose


def test_transport_advances_on_leader_progress_and_detects_home():
    c = Coordinator(100)
    hello(c, 1)
    touch(c, 1, 1, (-9, -9), 5, robot=(-10, -9))
    c.tick(5)
    pose = drive_home(c, [-10, -9])
    assert c.delivered_tick > 0
    assert (c.moved_x, c.moved_y) == (pose[0] + 10, pose[1] + 9)
    # the holder ended within 4 patches of home (the thesis's wayHome < 4)
    assert (pose[0] + 15) ** 2 + (pose[1] + 15) ** 2 < 16
    assert (pose[0] - c.dx + 15) ** 2 + (pose[1] - c.dy + 15) ** 2 >= 16


def test_blocked_step_tries_the_next_direction():
    c = Coordinator(100)
    hello(c, 1)
    touch(c, 1, 1, (0, 0), 5, robot=(0, -1))
    c.tick(5)
    first = (c.dx, c.dy)
    c.on_message(1, msg.HEARTBEAT, (4, 0, -256, 0, c.step), 6)     # did not move
    c.tick(6)
    assert (c.dx, c.dy) != first and c.blocked == 1


def test_replay_readopts_journalled_reports_without_double_counting_or_acks():
    journalled = []
    a = Coordinator(300, journal=lambda *r: journalled.append(r))
    hello(a, 1)
    touch(a, 1, 1, (5, 5), 10)
    b = Coordinator(300)
    for r in journalled + journalled:
        b.replay(*r)
    assert b.power == 100 and len(b.touches) == 1 and b.leader == 1
    assert b.tick(11) == [] and b.duplicates == 1


def test_a_touch_at_home_never_crashes_or_delivers() -> None:
    """A TOUCH at (-15,-15) raised ZeroDivisionError in step planning,
    and since the touch was journalled first, every resume crashed again. It
    is now rejected before the journal, and a journal that holds one (an
    older host's) is rejected on replay."""
    journalled = []
    c = Coordinator(600, journal=lambda *r: journalled.append(r))
    hello(c, 7, power=600)
    c.tick(1)
    touch(c, 7, 1, (-15, -15), 2, power=600, robot=(-15, -16))
    out = c.tick(2) + c.tick(3)
    assert journalled == [(7, msg.HELLO, (1, 600, 1), 1)]        # the touch is not
    assert c.touches == [] and c.rejected == {"segment at home": 1}
    assert c.converged_tick == -1 and c.delivered_tick == -1
    assert (7, msg.ACK, (1,)) not in out           # rejected reports are not ACKed
    r = Coordinator(600)
    hello(r, 7, power=600)
    r.replay(7, msg.TOUCH, (1, -15, -16, -15, -15, 600), 2)
    r.tick(4)
    r.tick(5)
    assert r.touches == [] and r.delivered_tick == -1 and r.rejected == {"segment at home": 1}


def test_step_planning_never_divides_by_zero() -> None:
    """The guard behind the rule: a host with no home radius accepts a touch
    exactly at home; planning finds no step closer and calls it delivered."""
    c = Coordinator(600, home_radius=0)
    hello(c, 7, power=600)
    touch(c, 7, 1, (-15, -15), 2, power=600, robot=(-15, -16))
    c.tick(2)
    assert c.converged_tick == 2 and c.delivered_tick == 2
    assert (msg.HOST, msg.HALT, (0,)) in c.tick(3)


def brute_plan(pts, mx, my):
    """_closer_h measured step by step with _least_d2."""
    from firmware_logic.behaviours.thesis.coordinator import STEPS, _least_d2
    here = _least_d2(pts, mx, my)
    want = []
    for dx, dy in STEPS:
        d = _least_d2(pts, mx + dx, my + dy)
        if d < here:
            want.append((d, len(want), dx, dy))
    return here, sorted(want)


def test_a_plans_ranking_is_every_step_closer_to_home_best_first() -> None:
    """_closer (one pass over the points for all nine displacements) ranks
    as measuring each step's least squared distance one by one does: the
    steps that bring it below here's, by that distance, ties to the step
    listed first."""
    import random

    from firmware_logic.behaviours.thesis.coordinator import _closer, _closer_h
    rng = random.Random(3)
    for _ in range(300):
        pts = [(rng.randint(-6, 6), rng.randint(-6, 6)) for _ in range(rng.randint(0, 9))]
        mx, my = rng.randint(-30, 30), rng.randint(-30, 30)
        want = brute_plan(pts, mx, my)
        assert _closer(pts, mx, my) == want[1]
        assert _closer_h(pts, mx, my) == want
    assert _closer([(0, 0)], 0, 0) == []          # at home: no step is closer


def test_a_plan_skips_only_points_that_cannot_be_nearest() -> None:
    """_ranked reads the points _within (measured at one displacement)
    has not ruled out for a plan up to `steps` steps each way from there,
    whichever point _squares put first (here the nearest to another place,
    copies of points among them): the ranking is the brute force's at every
    displacement within reach, and also when the first point is far from
    the nearest."""
    import random

    from firmware_logic.behaviours.thesis.coordinator import _ranked, _squares, _within
    rng = random.Random(11)
    for _ in range(300):
        pts = [(rng.randint(-6, 6), rng.randint(-6, 6)) for _ in range(rng.randint(1, 9))]
        pts += pts[:rng.randint(0, 2)]                  # copies
        fx, fy = rng.randint(-30, 30), rng.randint(-30, 30)
        sq = _squares(pts, fx, fy)
        assert sorted((s, 2 * x, 2 * y) for x, y in pts for s in [x * x + y * y]) == \
            sorted(q[:3] for q in sq)
        ax, ay = rng.randint(-30, 30), rng.randint(-30, 30)
        near = _within(sq, ax, ay)
        for _ in range(10):
            steps = rng.randint(0, 12)
            mx = ax + rng.randint(-steps, steps)
            my = ay + rng.randint(-steps, steps)
            assert _ranked(sq, mx, my, near, steps) == brute_plan(pts, mx, my)


def test_a_transport_plan_is_the_points_plan_wherever_the_object_goes() -> None:
    """A coordinator's plan (_rank, which measures _within again when the
    object has gone NEAR_STEPS steps) is the brute force's along a long
    random walk of the object, before and after a touch joins."""
    import random

    from firmware_logic.behaviours.thesis.coordinator import STEPS, Touch
    rng = random.Random(7)
    for _ in range(40):
        c = Coordinator(weight=100)
        for node in range(1, rng.randint(2, 8)):
            sx, sy = rng.randint(-4, 4), rng.randint(-2, 2)
            c.touches.append(Touch(node, 1, sx, sy - 1, sx, sy, 100, 1))
        remeasured = 0
        for k in range(120):
            if k % 30 == 0:
                way = STEPS[rng.randrange(8)]            # a heading for 30 ticks
            if rng.random() < 0.8:
                c.moved_x += way[0]
                c.moved_y += way[1]
            if k == 60:
                c.touches.append(Touch(99, 1, 5, 5, 5, 6, 100, 1))
            h = c._held()
            at = h[10][2:]
            pts = [(t.sx, t.sy) for t in c.touches]
            assert h[5] == pts
            assert c._rank(h) == brute_plan(pts, c.moved_x - c.home_x, c.moved_y - c.home_y)
            remeasured += h[10][2:] != at
        assert remeasured >= 2                   # the walk went beyond NEAR_STEPS


def test_arrival_skips_the_holders_pass_only_when_none_can_be_home() -> None:
    """_home_reached (segments within home_radius, else a live holder) skips
    the holders' pass when every segment is too far for a holder next to it
    to be home: the answer is the one both full passes give, at every
    displacement, however far a holder stands from its segment."""
    import random

    from firmware_logic.behaviours.thesis.coordinator import Touch, _least_d2
    rng = random.Random(5)
    for _ in range(200):
        c = Coordinator(weight=100, home_radius=rng.randint(1, 6))
        g = rng.randint(0, 3)
        for node in range(1, rng.randint(2, 6)):
            sx, sy = rng.randint(-3, 3), rng.randint(-3, 3)
            c.touches.append(Touch(node, 1, sx + rng.randint(-g, g), sy + rng.randint(-g, g),
                                   sx, sy, 100, 1))
        for _ in range(30):
            c.moved_x, c.moved_y = rng.randint(-30, 30), rng.randint(-30, 30)
            mx, my = c.moved_x - c.home_x, c.moved_y - c.home_y
            segs = [(t.sx, t.sy) for t in c.touches]
            live = [(t.rx, t.ry) for t in c.touches]
            want = 0 <= _least_d2(segs, mx, my) < c.home_r2 or \
                0 <= _least_d2(live, mx, my) < c.home_r2
            assert c._home_reached() == want
            assert c._home_reached(None, _least_d2(segs, mx, my)) == want
