"""A coordinator's `muted()` (firmware_logic/behaviours/thesis/coordinator.py)
lets the batch engine drop messages that would change nothing; these check
the promise on whole runs of the reference engine (every message it
declared muted, taken anyway, leaves the coordinator as it was) and that
the soa engine, which drops them, ends every run as the reference does."""

from firmware_logic import messages as msg
from sim_backend.batch.soa import SoaEngine
from sim_backend.engine import Engine
from sim_backend.scenario import validate


def state(c):
    """Everything a coordinator holds, comparable across a call."""
    return {k: repr(v) for k, v in vars(c).items() if k != "on_message"}


def run_checking_muted(sc, seed):
    """Run to the end; every message muted at the previous tick() is
    handed over anyway and must change nothing. Returns (muted seen,
    leader HEARTBEATs not muted during the transport)."""
    eng = Engine(sc, seed)
    c = eng.coordinator
    declared = [c.muted()]
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
        declared[0] = c.muted()
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


def test_the_soa_engine_drops_them_and_ends_as_the_reference():
    sc = validate({"maxTicks": 3000})
    eng = SoaEngine([(sc, 1), (sc, 2)])
    handed = [0]
    for r, hear in enumerate(eng._hear):
        def counted(node, kind, f, t, hear=hear):
            handed[0] += 1
            hear(node, kind, f, t)
        eng._hear[r] = counted
    sent = [0]
    step = eng._exchange

    def exchange(t):
        sent[0] += int(eng.out_n[0])
        return step(t)

    eng._exchange = exchange
    got = [r.summary() for r in eng.run()]
    assert got == [Engine(sc, s).run().summary() for s in (1, 2)]
    assert 0 < handed[0] < sent[0] // 2
