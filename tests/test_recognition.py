"""The host transports only what it recognises as the target
and releases the holders of decoys (scenario recognise = true)."""

import pytest

from firmware_logic import messages as msg
from firmware_logic.behaviours.thesis import recognising, spec
from firmware_logic.behaviours.thesis.coordinator import Coordinator
from firmware_logic.behaviours.thesis.robot import Robot
from firmware_logic.hal import OBJECT
from sim_backend import kernel
from sim_backend.engine import Engine
from sim_backend.errors import ScenarioError
from sim_backend.scenario import Scenario, load, validate
from tests.harness import assert_same

from tests.fakehal import FakeHal
from tests.test_coordinator import hello, touch


# -- scenario keys ----------------------------------------------------------------

def test_recognition_is_off_by_default_and_its_keys_are_checked():
    assert Scenario().recognise is False and Scenario().confidence == 0.9
    sc = load("decoy").replace(recognise=True, confidence=0.95)
    assert sc.recognise and sc.confidence == 0.95
    for bad, text in (({"recognise": 1}, "recognise: expected true or false, got 1"),
                      ({"recognise": "yes"}, "recognise: expected true or false"),
                      ({"confidence": 0.4}, "confidence: 0.4 is outside the allowed range"),
                      ({"confidence": 1.0}, "confidence: 1.0 is outside the allowed range"),
                      ({"confidence": "high"}, "confidence: expected float"),
                      ({"recognise": True, "behaviour": "aggregate"},
                       "scenario: unknown key 'recognise'; .*behaviour 'aggregate''s: ")):
        with pytest.raises(ScenarioError, match=text):
            validate(bad)


def test_scenarios_lists_the_keys(capsys):
    from bridge.cli import main
    assert main(["scenarios"]) == 0
    out = capsys.readouterr().out
    assert "recognise        false      true | false" in out
    assert "confidence       0.9        0.5..0.999" in out


def test_bad_keys_on_the_command_line_are_one_line_errors(capsys):
    from bridge.cli import main
    assert main(["run", "--scenario", "decoy", "--set", "confidence=2"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("touchswarm: error: confidence: 2") and "\n" not in err


# -- the coordinator with an injected decider ------------------------------------------

def _coordinator(verdicts, weight=200, journal=None):
    """A recognising coordinator whose decider answers by the cluster's first
    cell: verdicts maps a cell to a permille."""
    c = Coordinator(weight, journal=journal, world_size=18)
    c.recognition(900)
    asked = []

    def decider(cells, free):
        asked.append(sorted(cells))
        for cell in cells:
            if cell in verdicts:
                return verdicts[cell]
        return 500
    c.decider = decider
    return c, asked


def _kinds(out, kind):
    return [m for m in out if m[1] == kind]


def test_a_decoy_cluster_is_released_and_leaves_the_power_total():
    log = []
    c, asked = _coordinator({(5, 5): 990, (-10, 8): 20},
                            journal=lambda *a: log.append(a))
    for n in (1, 2, 3):
        hello(c, n)
    touch(c, 1, 1, (-10, 8), 2)            # the decoy
    touch(c, 2, 1, (-9, 9), 2)             # the decoy, next to it: one cluster
    touch(c, 3, 1, (5, 5), 2)              # the target, but short of the weight
    assert c.power == 300
    out = c.tick(2)
    rel = _kinds(out, spec.RELEASE)
    assert sorted(m[0] for m in rel) == [1, 2]
    assert rel[0][2] == (-12, 6, -7, 11)            # the box round the decoy's touches
    assert c.power == 100 and [t.node for t in c.touches] == [3]
    assert c.releases == 2 and c.converged_tick < 0
    assert c.target_tick == 2 and c.target_p == 990 and c.leader == 3
    # journalled before sent: a resumed host replays the release
    assert [e[1] for e in log].count(spec.RELEASE) == 2
    fresh = Coordinator(200, world_size=18)
    fresh.recognition(900)
    for node, kind, f, tick in log:
        fresh.replay(node, kind, f, tick)
    assert fresh.power == 100 and [t.node for t in fresh.touches] == [3]
    assert fresh.releases == 2 and fresh.leader == 3
    # the decoy was asked once, the target once; nothing new: nothing asked
    assert len(asked) == 2
    c.tick(3)
    assert len(asked) == 2


def test_transport_starts_only_on_a_recognised_target_with_enough_power():
    c, _ = _coordinator({(5, 5): 990})
    for n in (1, 2, 3):
        hello(c, n)
    touch(c, 1, 1, (5, 5), 2)
    c.tick(2)
    assert c.converged_tick < 0 and not c.quiet()
    touch(c, 2, 1, (6, 5), 3)
    out = c.tick(3)
    assert c.converged_tick == 3 and _kinds(out, msg.TRANSPORT)


def test_an_undecided_cluster_never_moves_and_a_stray_is_released():
    c, asked = _coordinator({})                # 500: neither target nor decoy
    for n in (1, 2, 3, 4):
        hello(c, n)
    touch(c, 1, 1, (5, 5), 2)
    touch(c, 2, 1, (6, 5), 2)
    touch(c, 3, 1, (7, 5), 2)
    for tick in range(2, 200):
        assert not _kinds(c.tick(tick), msg.TRANSPORT)
    assert c.converged_tick < 0 and c.releases == 0
    # asked again only when free evidence grew
    n = len(asked)
    c.on_message(4, msg.HEARTBEAT, (spec.SEARCH, 0, 0, 0, 0), 200)
    c.tick(200 + recognising.DECIDE_EVERY)
    assert len(asked) == n + 1


def test_other_clusters_are_released_when_the_target_converges():
    c, _ = _coordinator({(5, 5): 990})
    for n in (1, 2, 3):
        hello(c, n)
    touch(c, 1, 1, (-10, -10), 2)          # undecided (500)
    touch(c, 2, 1, (5, 5), 2)
    touch(c, 3, 1, (6, 5), 2)
    out = c.tick(2)
    assert c.converged_tick == 2
    assert [m[0] for m in _kinds(out, spec.RELEASE)] == [1]
    assert sorted(m[0] for m in _kinds(out, msg.TRANSPORT)) == [2, 3]


def test_a_touch_off_the_carried_object_during_the_transport_is_released():
    c, _ = _coordinator({(5, 5): 990})
    for n in (1, 2, 3, 4):
        hello(c, n)
    touch(c, 1, 1, (5, 5), 2)
    touch(c, 2, 1, (6, 5), 2)
    c.tick(2)
    assert c.converged_tick == 2
    touch(c, 3, 1, (7, 6), 3)              # on the carried object: a carrier too
    touch(c, 4, 1, (-10, -10), 3)          # another object
    out = c.tick(3)
    assert [m[0] for m in _kinds(out, spec.RELEASE)] == [4]
    assert sorted(t.node for t in c.touches) == [1, 2, 3] and c.power == 300


def test_a_holder_that_missed_its_release_gets_it_again():
    c, _ = _coordinator({(-10, 8): 20})
    hello(c, 1)
    touch(c, 1, 1, (-10, 8), 2)
    first = _kinds(c.tick(2), spec.RELEASE)
    assert first
    c.on_message(1, msg.HEARTBEAT, (spec.HOLD, -10 * 256, 7 * 256, 0, 0), 70)
    assert _kinds(c.tick(70), spec.RELEASE) == first
    c.on_message(1, msg.HEARTBEAT, (spec.SEARCH, 0, 0, 0, 0), 134)
    assert not _kinds(c.tick(134), spec.RELEASE)


def test_released_touches_stay_evidence_for_the_next_cluster_there():
    c, asked = _coordinator({(-10, 8): 20})
    hello(c, 1)
    hello(c, 2)
    touch(c, 1, 1, (-10, 8), 2)
    c.tick(2)
    touch(c, 2, 1, (-8, 10), 5)
    out = c.tick(5)
    assert asked[-1] == [(-10, 8), (-8, 10)]       # the released touch joins the evidence
    assert [m[0] for m in _kinds(out, spec.RELEASE)] == [2]


def test_off_recognition_the_coordinator_is_unchanged():
    c = Coordinator(200)
    assert c.recognise == 0 and c.measures() == {"outcome": "collecting touches"}
    assert "releases" not in c.snapshot() or c.snapshot()["releases"] == 0


# -- the robot -----------------------------------------------------------------------

def _hal():
    """An OBJECT one patch ahead at every heading."""
    hal = FakeHal()
    hal.probe_default = OBJECT
    return hal


def test_a_released_robot_lets_go_and_leaves_the_box_alone_for_a_while():
    r = Robot(1, 7, spec.FIREFLY, 45, 2, 100)
    hal = _hal()
    r.step(hal)                               # claims the segment ahead
    r.step(hal)                               # holds it
    assert r.state == spec.HOLD
    hal.log.clear()
    hal.inbox.append((spec.RELEASE, (-2, -2, 2, 2)))
    r.step(hal)
    assert r.state == spec.SEARCH and ("beacon", 0) in hal.log
    assert [c[1] for c in hal.calls("forward")] == [(r.claim_heading + 180) % 360]
    for _ in range(spec.RELEASE_TICKS - 1):  # every segment ahead is in the box
        hal.log.clear()
        r.step(hal)
        assert not hal.calls("claim")
    hal.log.clear()
    r.step(hal)                              # the hold-off is over
    assert hal.calls("claim")


def test_a_release_in_another_state_is_ignored():
    r = Robot(1, 7, spec.FIREFLY, 45, 2, 100)
    hal = _hal()
    hal.inbox.append((spec.RELEASE, (-2, -2, 2, 2)))
    r.step(hal)
    assert r.avoid_ticks == 0 and r.state == spec.GRASP


def test_a_forward_lets_go_of_the_held_segment():
    sc = validate({})
    e = Engine(sc, 1)
    w = e.world
    cx, cy = w.object_cells[0]
    k = w.idx(cx, cy)
    w.obj[k] = kernel.BLUE
    w.owner[k] = 1
    w.held[0] = k
    w.mv_on[0] = 1
    w.mv_h[0] = 0
    w.mv_step[0] = 0
    w.apply(1)
    assert w.held[0] == -1 and w.obj[k] == kernel.YELLOW and w.owner[k] == 0


# -- whole runs --------------------------------------------------------------------

def _decoy_cells(sc):
    return {c for p in sc.pieces()[1:] for c in p.placed(*p.at)}


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_the_decoy_scenario_brings_the_target_home_and_leaves_the_decoy(seed):
    sc = load("decoy").replace(recognise=True)
    e = Engine(sc, seed)
    decoy = _decoy_cells(sc)
    released_at: dict[int, int] = {}
    let_go: dict[int, int] = {}
    while not e.finished():
        e.step()
        c = e.coordinator
        for node in c.released:
            released_at.setdefault(node, e.tick)
        for node, t0 in released_at.items():
            k = e.world.held[node - 1]
            if k < 0:
                let_go.setdefault(node, e.tick)     # it let go (a tick after the RELEASE)
            elif node in let_go and e.tick - let_go[node] < recognising.HOLDOFF - 2:
                # a released robot does not claim the decoy again at once
                assert (k % e.world.n - e.world.w, k // e.world.n - e.world.w) not in decoy
        assert all(t - released_at[n] <= 2 for n, t in let_go.items())
    s = e.run().summary()
    assert s["delivered"] and s["wrong_transport"] is False
    assert s["target_tick"] is not None and s["target_permille"] >= 900
    assert s["target_tick"] <= s["converged_tick"]
    assert not any((x, y) in decoy for x, y in s["segments"])
    assert s["releases"] >= len(released_at) == len(let_go)


def test_a_decoy_is_released_in_some_run():
    sc = load("decoy").replace(recognise=True)
    total = sum(Engine(sc, seed).run().summary()["releases"] for seed in (1, 2, 3))
    assert total > 0


def test_recognition_runs_the_same_in_the_batch_engine():
    sc = load("decoy").replace(recognise=True)
    got = assert_same([sc, sc], [1, 2])
    assert all(r.delivered for r in got)
    assert sum(r.coordinator.releases for r in got) > 0


def test_a_resumed_host_replays_the_release_from_its_journal(tmp_path):
    from bridge.host.journal import Journal, Report
    with Journal(tmp_path / "j.sqlite") as j:
        c, _ = _coordinator({(5, 5): 990, (-10, 8): 20}, journal=j.add_report)
        for n in (1, 2):
            hello(c, n)
        touch(c, 1, 1, (-10, 8), 2)
        touch(c, 2, 1, (5, 5), 2)
        c.tick(2)
        assert c.power == 100 and c.releases == 1
    with Journal(tmp_path / "j.sqlite") as j:
        fresh = Coordinator(200, world_size=18)
        fresh.recognition(900)
        kinds = []
        for e in j.entries():
            if isinstance(e, Report):
                kinds.append(e.kind)
                fresh.replay(e.node, e.kind, e.fields, e.tick)
    assert spec.RELEASE in kinds
    assert fresh.power == 100 and [t.node for t in fresh.touches] == [2]
    assert fresh.released == {1: c.released[1]} and fresh.leader == 2


def test_over_virtual_can_recorded_and_replayed(tmp_path, capsys):
    import json

    from bridge.cli import main
    f = tmp_path / "r.log"
    assert main(["run", "--scenario", "decoy", "--set", "recognise=true", "--link", "can",
                 "--record", str(f), "--json"]) == 0
    s = json.loads(capsys.readouterr().out)
    assert s["delivered"] and s["releases"] >= 1 and s["wrong_transport"] is False
    # the RELEASE frame (kind 8: identifiers 0x400-0x47F) is on the recording
    ids = [int(line.split()[2].split("#")[0], 16) for line in f.read_text().splitlines()]
    assert any(msg.split_id(i)[0] == spec.RELEASE for i in ids)
    assert main(["replay", str(f)]) == 0
    assert "0 divergences" in capsys.readouterr().out


def test_touches_on_one_object_of_the_map_are_one_cluster():
    c, asked = _coordinator({})
    c.objects = [frozenset((x, 5) for x in range(0, 10))]
    hello(c, 1)
    hello(c, 2)
    touch(c, 1, 1, (0, 5), 2)
    touch(c, 2, 1, (9, 5), 2)              # 9 apart, but one object on the map
    c.tick(2)
    assert asked == [[(0, 5), (9, 5)]]
