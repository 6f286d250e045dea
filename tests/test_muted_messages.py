"""A coordinator's `muted()` (firmware_logic/behaviours/thesis/coordinator.py)
lets both engines drop messages that would change nothing
(sim_backend/exchange.py); these check the promise on whole runs of the
reference engine told to hear everything (every message declared muted,
taken anyway, leaves the coordinator as it was) and that the soa engine
drops them and ends every run as the reference does."""

from types import SimpleNamespace

from firmware_logic import messages as msg
from sim_backend.batch.soa import SoaEngine
from sim_backend.engine import Engine, InprocLink
from sim_backend.exchange import muting
from sim_backend.scenario import validate


def state(c):
    """Everything a coordinator holds, comparable across a call."""
    return {k: repr(v) for k, v in vars(c).items()
            if k not in ("on_message", "tick", "muted", "idle_until")}


class Lossy(InprocLink):
    """Loses every seventh TRANSPORT: the coordinator's resend ticks come."""

    def __init__(self, nodes):
        super().__init__(nodes)
        self.transports = 0

    def send(self, node, kind, fields):
        if kind == msg.TRANSPORT:
            self.transports += 1
            if self.transports % 7 == 0:
                return
        super().send(node, kind, fields)


def run_checking_muted(sc, seed, link=None):
    """Run to the end; every message muted at the previous tick() (by the
    rule, exchange.Muting.drops) is handed over anyway and must change
    nothing, and every tick() before the coordinator's idle_until() with no
    other message since must change nothing and send nothing. Returns
    (result, counts: muted, repeats of the leader's muted, idle ticks,
    leader HEARTBEATs heard during the transport)."""
    eng = Engine(sc, seed, link=link)
    c = eng.coordinator
    muted = c.muted
    c.muted = lambda: None           # the engine hands every message over
    declared = [muting(SimpleNamespace(muted=muted))]
    idle = [c.idle_until()]
    counts = {"muted": 0, "repeat": 0, "idle": 0, "leader": 0}
    hear, tick = c.on_message, c.tick

    def on_message(node, kind, f, t):
        m = declared[0]
        if m.drops(node, kind, f):
            before = state(c)
            hear(node, kind, f, t)
            assert state(c) == before, (node, kind, f, t)
            counts["repeat" if node == m.node else "muted"] += 1
            return
        idle[0] = 0                  # a message that counts: the next tick() may act
        if kind == msg.HEARTBEAT and c.step > 0 and node == c.leader:
            counts["leader"] += 1
        hear(node, kind, f, t)

    def on_tick(t):
        if t < idle[0]:
            before = state(c)
            out = tick(t)
            assert out == [] and state(c) == before, t
            counts["idle"] += 1
        else:
            out = tick(t)
        declared[0] = muting(SimpleNamespace(muted=muted))
        idle[0] = c.idle_until()
        return out

    c.on_message, c.tick = on_message, on_tick
    res = eng.run()
    return res, counts


def test_every_muted_message_and_idle_tick_changes_nothing_and_the_leader_is_heard():
    plain = validate({"maxTicks": 3000})
    for sc, seed, link in ((plain, 1, None), (plain, 2, Lossy(list(range(1, 21)))),
                           (validate({"maxTicks": 3000, "arrival": "netlogo",
                                      "activation": "netlogo"}), 3, None)):
        res, counts = run_checking_muted(sc, seed, link)
        assert res.summary()["delivered"]
        assert counts["muted"] > 100          # the holders' HEARTBEATs, carrying
        assert counts["leader"] > 10          # the transport follows the leader's
        assert counts["repeat"] > 10          # ... but not its unchanged repeats
        assert counts["idle"] > 10            # nor ticks while a step is under way


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


def test_soa_asks_no_idle_coordinator_and_ends_as_without_the_declarations():
    """The soa engine calls tick() only on a coordinator that heard a
    message since its last one or whose idle_until() has come; the same
    runs with the declarations taken away (every leader HEARTBEAT handed
    over, every transport tick asked) end alike, with more calls."""
    sc = validate({"maxTicks": 3000})
    runs = [(sc, 1), (sc, 2), (sc.replace(activation="netlogo"), 3)]

    def watched(plain):
        eng = SoaEngine(runs)
        calls = [0, 0]                 # tick() calls, on_message calls
        for c in eng.coords:
            if plain:
                c.idle_until = lambda: 0
                c.muted = lambda m=c.muted: None if m() is None else m()[:3]
            state = {"heard": False, "idle": 0}
            hear, tick = c.on_message, c.tick

            def on_message(node, kind, f, t, hear=hear, state=state):
                calls[1] += 1
                state["heard"] = True
                hear(node, kind, f, t)

            def on_tick(t, c=c, tick=tick, state=state):
                assert state["heard"] or t >= state["idle"], t
                calls[0] += 1
                out = tick(t)
                state["heard"], state["idle"] = False, c.idle_until()
                return out
            c.on_message, c.tick = on_message, on_tick
        return [r.summary() for r in eng.run()], calls

    got, calls = watched(False)
    want, plain_calls = watched(True)
    assert got == want
    assert calls[0] < plain_calls[0] and calls[1] < plain_calls[1], (calls, plain_calls)
