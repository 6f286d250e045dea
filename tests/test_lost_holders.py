"""What the host does when a holder dies (lostAfter > 0).

The coordinator counts each holder's silence in its own ticks: a holder not
heard for more than lost_after ticks is lost (its power leaves the total, a
new leader is chosen among the live holders, its cell becomes an obstacle),
the transport pauses while the power is short of the weight and goes on
when new touches bring it back; a lost holder heard again is taken back;
every change is a decision journalled with its snapshot, so a resumed host
agrees. Blocked transport steps are remembered and planned round.
Everything here runs in process on the tick counter (no clock).
"""

import pytest

from firmware_logic import messages as msg
from firmware_logic.behaviours.thesis.coordinator import Coordinator
from sim_backend import faults
from sim_backend.engine import Engine
from sim_backend.errors import ScenarioError
from sim_backend.scenario import validate
from tests.harness import assert_same

LOST = 70


def hello(c, node, power=100, tick=1):
    c.on_message(node, msg.HELLO, (1, power, 1), tick)


def touch(c, node, seg, robot, tick, power=100):
    c.on_message(node, msg.TOUCH, (1, robot[0], robot[1], seg[0], seg[1], power), tick)


def beat(c, node, pose, done, tick):
    c.on_message(node, msg.HEARTBEAT, (4, pose[0] * 256, pose[1] * 256, 0, done), tick)


class Host:
    """The host process's loop in miniature: reports journalled as they are
    accepted, each tick's decision journalled with its snapshot."""

    def __init__(self, weight=200, **kw):
        self.log = []
        self.c = Coordinator(weight, journal=lambda *r: self.log.append(("r",) + r),
                             lost_after=LOST, **kw)
        self.decisions = []

    def tick(self, t):
        before = self.c.snapshot()
        out = self.c.tick(t)
        d = self.c.decision(before, out)
        if d is not None:
            self.log.append(("d", self.c.snapshot()))
            self.decisions.append((t,) + d)
        return out


def transports(out):
    return sorted(m[0] for m in out if m[1] == msg.TRANSPORT)


def converged_pair():
    """Robots 1 (leader) and 2 hold a 200 object at tick 12; robot 3 searches."""
    h = Host()
    for n in (1, 2, 3):
        hello(h.c, n)
    h.tick(1)
    touch(h.c, 1, (5, 5), (5, 4), 10)
    h.tick(10)
    touch(h.c, 2, (6, 5), (6, 4), 12)
    out = h.tick(12)
    assert h.c.converged_tick == 12 and transports(out) == [1, 2]
    return h


def test_a_silent_leader_is_lost_the_transport_pauses_and_resumes_with_new_power():
    h = converged_pair()
    c = h.c
    # robot 2 carries and reports every tick, the leader never again
    t = 13
    while not c.lost:
        beat(c, 2, (6, 4), 0, t)
        h.tick(t)
        t += 1
    assert t - 1 == 10 + LOST + 1           # last heard at its touch, tick 10
    assert c.lost == (1,) and c.lost_cells == (5, 4)
    assert c.power == 100 and c.leader == 2 and c.carriers() == [2]
    assert h.decisions[-1][1] == "lost"
    # power short of the weight: no command goes out while robot 3 is away
    for t in range(t, t + 40):
        beat(c, 2, (6, 4), 0, t)
        assert transports(h.tick(t)) == []
    assert c.stopped_tick < 0 and not c.done()
    # robot 3 claims the freed segment: power is back, the transport goes on
    touch(c, 3, (5, 5), (4, 5), t + 1)
    out = h.tick(t + 1)
    assert c.power == 200 and set(transports(out + h.tick(t + 5))) == {2, 3}


def test_the_new_leader_drives_the_transport_to_delivery():
    h = Host(weight=100)
    c = h.c
    for n in (1, 2):
        hello(c, n)
    touch(c, 1, (-5, -5), (-5, -4), 10)
    touch(c, 2, (-6, -5), (-6, -4), 10)
    h.tick(10)
    assert c.converged_tick == 10 and c.leader == 1
    pose = [-6, -4]
    t = 11
    while not c.done() and t < 400:
        step = c.step
        if t > 20:                           # robot 1 dies at tick 20
            pose = [pose[0] + c.dx, pose[1] + c.dy] if c.leader == 2 else pose
        beat(c, 2, pose, step if c.leader == 2 else 0, t)
        if t <= 20:
            beat(c, 1, (pose[0] + 1, pose[1]), step, t)
        h.tick(t)
        t += 1
    assert c.lost == (1,) and c.leader == 2
    assert c.delivered_tick > 20 + LOST, c.status()


def leader_lost():
    """converged_pair, then robot 2 alone reports until the leader is lost."""
    h = converged_pair()
    for t in range(13, 13 + LOST + 2):
        beat(h.c, 2, (6, 4), 0, t)
        h.tick(t)
    return h


def test_a_lost_holder_heard_again_is_taken_back():
    h = leader_lost()
    c = h.c
    assert c.lost == (1,) and c.power == 100
    beat(c, 1, (5, 4), 0, 100)
    h.tick(100)
    assert c.lost == () and c.lost_cells == () and c.power == 200 and c.leader == 1
    assert c.carriers() == [1, 2]


def test_a_resumed_host_agrees_on_lost_holders():
    h = leader_lost()
    c = h.c
    assert c.lost == (1,)
    r = Coordinator(200, lost_after=LOST)
    for e in h.log:
        if e[0] == "r":
            r.replay(*e[1:])
        else:
            r.adopt(e[1])
    assert r.snapshot() == c.snapshot()
    assert (r.power, r.leader, r.carriers()) == (c.power, c.leader, c.carriers()) == \
        (100, 2, [2])
    # both go on alike: robot 3's touch restarts the same transport
    for x in (c, r):
        touch(x, 3, (5, 5), (4, 5), 90)
    assert c.tick(90) == r.tick(90)


def test_off_by_default_a_silent_leader_is_waited_for():
    c = Coordinator(100)
    hello(c, 1)
    touch(c, 1, (5, 5), (5, 4), 10)
    c.tick(10)
    for t in range(11, 2000):
        c.tick(t)
    assert c.lost == () and c.power == 100 and c.carriers() == [1]


def test_a_blocked_step_is_remembered_and_planned_round():
    c = Coordinator(100, lost_after=LOST)
    hello(c, 1)
    touch(c, 1, (0, 0), (0, -1), 5)
    c.tick(5)
    tried = set()
    for t in range(6, 13):              # the object never moves: every step blocked
        tried.add((c.dx, c.dy))
        beat(c, 1, (0, -1), c.step, t)
        c.tick(t)
    tried.add((c.dx, c.dy))
    # seven blocked, each remembered; the eighth step is the last untried one
    assert len(tried) == 8 and len(c.bumps) == 2 * 7


def test_blocked_everywhere_forgets_the_bumps_instead_of_stopping():
    c = Coordinator(100, lost_after=LOST)
    hello(c, 1)
    touch(c, 1, (0, 0), (0, -1), 5)
    c.tick(5)
    for t in range(6, 40):
        beat(c, 1, (0, -1), c.step, t)
        c.tick(t)
    assert c.stopped_tick < 0 and len(c.bumps) < 2 * 8


@pytest.mark.parametrize("bad", [1, 64, -1, "x"])
def test_lost_after_out_of_range_is_one_line(bad):
    with pytest.raises(ScenarioError) as err:
        validate({"lostAfter": bad})
    assert "lostAfter" in str(err.value) and "\n" not in str(err.value)
    assert validate({"lostAfter": 65}).lostAfter == 65 and validate({}).lostAfter == 0


GOAL = {"deathRate": 0.25, "ignoreFieldRate": 0.1, "randomRate": 0.1, "faultWindow": 200,
        "maxTicks": 3000}


def test_a_dead_leader_no_longer_stops_the_delivery():
    """Seed 1 of the goal mix: the leader dies during the transport. The
    thesis's host waits for it for ever; with lostAfter it delivers."""
    sc = validate(GOAL)
    die = faults.plan(sc, 1)[0]
    before = Engine(sc, 1).run()
    leader = before.coordinator.leader
    assert not before.delivered and die[leader - 1] < before.ticks
    after = Engine(validate({**GOAL, "lostAfter": 100}), 1).run()
    assert after.delivered and leader in after.coordinator.lost


def test_lost_after_is_equal_in_both_engines():
    scs = [validate({**GOAL, "lostAfter": 100})] * 3
    got = assert_same(scs, [1, 2, 14])
    assert any(r.coordinator.lost for r in got)


def test_without_faults_nobody_is_lost_and_only_blocked_steps_are_planned_differently():
    """lostAfter is a host rule: until a transport step is blocked (then
    the plan goes round it) the run is the thesis host's, tick for tick."""
    a = Engine(validate({"maxTicks": 1500}), 4, record_trajectories=True).run()
    b = Engine(validate({"maxTicks": 1500, "lostAfter": 100}), 4,
               record_trajectories=True).run()
    assert a.delivered and b.delivered and b.coordinator.lost == ()
    conv = a.coordinator.converged_tick
    assert b.coordinator.converged_tick == conv
    assert a.trajectories[:conv + 1] == b.trajectories[:conv + 1]


def test_why_a_run_failed_is_diagnosed_and_a_pinned_object_is_not_feasible():
    from sim_backend.robustness import fault_table, why_table
    assert why_table({**GOAL, "lostAfter": 0}, [1]) == {"leader dead": [1]}
    # seed 35 under crowd "block": two dead holders pin the object (a bar
    # with carriers at both ends) against them; no way home exists for anyone
    assert why_table({**GOAL, "lostAfter": 100, "crowd": "block"}, [1, 35]) == \
        {"delivered": [1], "no path home": [35]}
    row = {"experiment": "goal", "seed": 35, "deathRate": 0.25, "ignoreFieldRate": 0.1,
           "randomRate": 0.1, "delivered": False, "home_tick": None}
    pinned = fault_table([{**row, "outcome": "no path home"}], "goal")
    stalled = fault_table([{**row, "outcome": "stalled"}], "goal")
    assert pinned["goal"] == [(-1.0, 0, 0, None)]
    assert stalled["goal"] == [(-1.0, 1, 0, None)]


def test_under_yield_a_lost_holders_cell_is_not_planned_round():
    """Under crowd "yield" (the default) the world pushes a dead robot aside
    like any bystander, so the host does not plan round a lost holder's
    cell: seeds 14, 35 and 38 of the goal mix, which ended "no path home"
    when it did, deliver; under "block" it still plans round them."""
    from sim_backend.robustness import why_table
    assert why_table({**GOAL, "lostAfter": 100}, [14, 35, 38]) == {"delivered": [14, 35, 38]}
    y = Engine(validate({**GOAL, "lostAfter": 100}), 35).run().coordinator
    b = Engine(validate({**GOAL, "lostAfter": 100, "crowd": "block"}), 35).run().coordinator
    assert y.crowd_yields and not b.crowd_yields
    assert y.lost_cells and y._closed_now() == y.closed
    cells = set(zip(b.lost_cells[::2], b.lost_cells[1::2]))
    assert cells and cells <= set(b._closed_now())
