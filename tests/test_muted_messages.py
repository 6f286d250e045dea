"""A coordinator's `muted()` (firmware_logic/behaviours/thesis/coordinator.py)
lets both engines drop messages that would change nothing
(sim_backend/exchange.py); these check the promise on whole runs of the
reference engine told to hear everything (every message declared muted,
taken anyway, leaves the coordinator as it was) and that the soa engine
drops them and ends every run as the reference does."""

from firmware_logic import messages as msg
from sim_backend.batch.soa import SoaEngine
from sim_backend.engine import Engine
from sim_backend.scenario import validate


def state(c):
    """Everything a coordinator holds, comparable across a call."""
    return {k: repr(v) for k, v in vars(c).items() if k not in ("on_message", "tick", "muted")}


def run_checking_muted(sc, seed):
    """Run to the end; every message muted at the previous tick() is
    handed over anyway and must change nothing. Returns (muted seen,
    leader HEARTBEATs not muted during the transport)."""
    eng = Engine(sc, seed)
    c = eng.coordinator
    muted = c.muted
    declared = [muted()]
    c.muted = lambda: None           # the engine hands every message over
    counts = {"muted": 0, "leader": 0}
    hear, tick = c.on_message, c.tick

    def on_message(node, kind, f, t):
        m = declared[0]
        if m is not None and kind == m[0] and node in m[1] and node != m[2]:
            before = state(c)
            hear(node, kind, f, t)
            assert state(c) == before, (node, kind, f, t)
            counts["muted"] += 1
            return
        if kind == msg.HEARTBEAT and c.step > 0 and node == c.leader:
            counts["leader"] += 1
        hear(node, kind, f, t)

    def on_tick(t):
        out = tick(t)
        declared[0] = muted()
        return out

    c.on_message, c.tick = on_message, on_tick
    res = eng.run()
    return res, counts


def test_every_muted_message_changes_nothing_and_the_leader_is_heard():
    sc = validate({"maxTicks": 3000})
    for seed in (1, 2):
        res, counts = run_checking_muted(sc, seed)
        assert res.summary()["delivered"]
        assert counts["muted"] > 100          # the holders' HEARTBEATs, carrying
        assert counts["leader"] > 10          # the transport follows the leader's


def test_liveness_and_recognition_mute_nothing():
    assert Engine(validate({"lostAfter": 200}), 1).coordinator.muted() is None
    c = Engine(validate({}), 1).coordinator
    c.recognise = 1
    assert c.muted() is None


def counting(c, handed):
    """c's on_message, counting the messages handed to it in handed[0]."""
    def counted(node, kind, f, t, hear=c.on_message):
        handed[0] += 1
        hear(node, kind, f, t)
    c.on_message = counted


def test_both_engines_drop_them_alike_and_end_alike():
    sc = validate({"maxTicks": 3000})
    eng = SoaEngine([(sc, 1), (sc, 2)])
    handed = [0]
    for c in eng.coords:
        counting(c, handed)
    sent = [0]
    step = eng._exchange

    def exchange(t):
        sent[0] += int(eng.out_n[0])
        return step(t)

    eng._exchange = exchange
    got = [r.summary() for r in eng.run()]
    ref_handed, want = [0], []
    for s in (1, 2):
        ref = Engine(sc, s)
        counting(ref.coordinator, ref_handed)
        res = ref.run()
        want.append(res.summary())
    assert got == want
    assert 0 < handed[0] < sent[0] // 2
    assert ref_handed == handed           # the same messages reach the coordinators
