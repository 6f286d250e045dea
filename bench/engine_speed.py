"""Robot-ticks per second of the two engines, side by side, one core.

Prints one JSON object. Each size runs the same scenario and seeds in the
per-robot reference engine (the per-agent Python baseline, Mesa-style) and
the struct-of-arrays batch engine transformed from the behaviour's own
source (with its cold and warm start in fresh processes), over the same
ticks from the same start: the first tick is stepped apart (set-up and
compilation are excluded from the rates and reported apart; both engines
include the host coordinators), the rest in ten rounds that step the
engines in turn, so a neighbour slowing the shared machine for a while
slows both alike (it moved one engine's figure by half between two runs
when each ran its ticks in one go). The bench checks that both end with
identical robot positions, and reports the ratio. "20x500" is 500
independent 20-robot runs stepped as one batch, the way sweeps use it. (The
hand-vectorised numpy engine and the jitclass engine this bench also timed
until they were retired have their last side-by-side figures in
docs/performance.md.)

Rates are robot-ticks per second of this process's CPU time
(`time.process_time`; every engine runs on one pinned core, numba and
numpy single-threaded), so a busy neighbour on the shared machine stretches
the wall time but not the figures; each size also reports the wall seconds
of the same steps (`wall_s`) to show how loaded the machine was.

    .venv/bin/python bench/engine_speed.py [--quick]
"""

import json
import os
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
try:
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
except (AttributeError, OSError):
    pass

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from sim_backend.engine import Engine  # noqa: E402
from sim_backend.scenario import validate  # noqa: E402
from sim_backend.batch import body as B  # noqa: E402
from sim_backend.batch.soa import SoaEngine  # noqa: E402

# robots -> (worldSize, ticks, runs). Every engine steps the same ticks from the
# same start: a run's ticks are not alike (the first, with every robot searching,
# are the reference's cheapest), so a rate over fewer reference ticks than
# compiled ones would compare different work.
SIZES = {
    "20": (18, 400, 1),
    "20x500": (18, 200, 500),
    "1000": (40, 400, 1),
    "10000": (150, 200, 1),
}


def scenario(robots, world):
    return validate({"agents": robots, "worldSize": world, "maxTicks": 10_000_000})


ROUNDS = 10    # the timed ticks are stepped in this many rounds, the engines in turn


class Timed:
    """One engine over a size's runs: its first tick apart (it compiles, or
    loads, the step; the reference steps it too, so all start timing at the
    same tick), then steps timed by CPU and wall clock."""

    def __init__(self, name, sc, seeds):
        self.name, self.cpu, self.wall = name, 0.0, 0.0
        t0 = time.perf_counter()
        if name == "reference":
            self.engines = [Engine(sc, s) for s in seeds]
        else:
            self.engines = [SoaEngine([(sc, s) for s in seeds])]
        self._step()
        self.setup = time.perf_counter() - t0

    def _step(self):
        for e in self.engines:
            e.step()

    def steps(self, k):
        c, w = time.process_time(), time.perf_counter()
        for _ in range(k):
            self._step()
        self.cpu += time.process_time() - c
        self.wall += time.perf_counter() - w

    def positions(self):
        """Every run's robot positions (None for a run the batch finished)."""
        if self.name == "reference":
            return [(list(e.world.xs), list(e.world.ys)) for e in self.engines]
        be = self.engines[0]
        out = []
        for r in range(len(be.runs)):
            if not be.rt[B.LIVE, r]:   # delivered early, the reference steps on
                out.append(None)
                continue
            a, b = int(be.rt[B.LO, r]), int(be.rt[B.HI, r])
            out.append((be.rb[B.XS, a:b].tolist(), be.rb[B.YS, a:b].tolist()))
        return out


def time_engines(sc, seeds, ticks):
    """The engines over the same ticks 2..ticks, interleaved: ROUNDS
    rounds, each engine stepping its share in turn (the order rotating), so
    a neighbour that slows the shared machine for a while slows both."""
    engines = [Timed(name, sc, seeds) for name in ("reference", "soa")]
    left = ticks - 1
    for k in range(ROUNDS):
        share = left // (ROUNDS - k)
        left -= share
        for j in range(len(engines)):
            engines[(k + j) % len(engines)].steps(share)
    return {e.name: e for e in engines}


SOA_START = """
import json, time
t0 = time.perf_counter()
from sim_backend.batch.soa import SoaEngine
from sim_backend.scenario import validate
SoaEngine([(validate({"agents": 20, "worldSize": 18}), 1)]).step()
print(json.dumps(round(time.perf_counter() - t0, 2)))
"""


def soa_starts():
    """Seconds to the first SoA tick in a fresh process: with an empty disk
    cache (cold), then again with the cache the first one wrote (warm)."""
    import subprocess
    import tempfile
    root = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "TOUCHSWARM_CACHE": cache, "PYTHONPATH": root}
        out = [json.loads(subprocess.run([sys.executable, "-c", SOA_START], env=env,
                                         check=True, capture_output=True,
                                         text=True).stdout.strip().splitlines()[-1])
               for _ in range(2)]
    return out


def main():
    quick = "--quick" in sys.argv
    res = {"cores": 1, "clock": "process CPU seconds (wall_s: wall seconds)", "sizes": {}}
    res["soa_cold_start_s"], res["soa_warm_start_s"] = soa_starts()
    SoaEngine([(scenario(20, 18), 1)]).step()      # this process's SoA (cache as it is)
    for name, (world, ticks, runs) in SIZES.items():
        robots = int(name.split("x")[0])
        if quick:
            ticks = max(ROUNDS + 1, ticks // 10)
        sc = scenario(robots, world)
        seeds = list(range(1, runs + 1))
        eng = time_engines(sc, seeds, ticks)
        n = robots * runs * (ticks - 1)
        rate = {k: n / e.cpu for k, e in eng.items()}
        ref = eng["reference"].positions()
        res["sizes"][name] = {
            "robots": robots, "runs": runs, "worldSize": world, "ticks": ticks,
            "timed_ticks": ticks - 1, "rounds": ROUNDS,
            **{k: {"seconds": round(e.cpu, 4), "wall_s": round(e.wall, 4),
                   "setup_s": round(e.setup, 3), "robot_ticks_per_s": round(rate[k])}
               for k, e in eng.items()},
            "ratio_soa_to_reference": round(rate["soa"] / rate["reference"], 2),
            "identical_positions": all(b is None or b == r
                                       for r, b in zip(ref, eng["soa"].positions())),
        }
    print(json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
