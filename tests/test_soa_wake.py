"""SoaEngine._exchange and _finish: a coordinator that heard nothing is asked
to tick exactly when its wake tick comes (sim_backend/exchange.py `wake`),
and a run that ended is never asked again, though its last wake tick comes
later (an engine built, not stepped: nothing compiles; no robot sends)."""

from sim_backend.batch import body as B
from sim_backend.batch.soa import SoaEngine
from sim_backend.exchange import NEVER, wake
from sim_backend.scenario import validate


class Waking:
    """A coordinator that needs a tick at each of `wakes` and ends the run
    when it ticks at `end` (or never: -1); it hears no message."""

    def __init__(self, wakes: list[int], end: int = -1) -> None:
        self.wakes, self.end = wakes, end
        self.asked: list[int] = []
        self.touches: list = []
        self.converged_tick = self.delivered_tick = -1

    def on_message(self, node: int, kind: int, fields: tuple, tick: int) -> None:
        raise AssertionError("no robot sends in this test")

    def tick(self, t: int) -> list:
        self.asked.append(t)
        return []

    def quiet(self) -> bool:
        return not self.wakes

    def idle_until(self) -> int:
        last = self.asked[-1] if self.asked else 0
        return min((w for w in self.wakes if w > last), default=NEVER)

    def done(self) -> bool:
        return self.end in self.asked

    def status(self) -> str:
        return ""


def test_a_coordinator_is_asked_at_its_wake_ticks_and_an_ended_run_never_again():
    sc = validate({"agents": 3, "objectWeight": 2, "maxTicks": 50})
    eng = SoaEngine([(sc, seed) for seed in (1, 2, 3, 4)])
    coords = [Waking([2, 5, 9]), Waking([4, 6, 11], end=4), Waking([]), Waking([7, 8], end=8)]
    eng.coords = coords
    eng.wake[:] = [wake(c) for c in coords]
    for t in range(1, 14):
        eng.tick = t
        eng.out_n[0] = 0                      # nothing sent this tick
        eng._finish(t, eng._exchange(t))
    assert [c.asked for c in coords] == [[2, 5, 9], [4], [], [7, 8]]
    assert eng.rt[B.LIVE].tolist() == [1, 0, 1, 0]
    assert [r is not None and r.ticks for r in eng.results] == [False, 4, False, 8]
