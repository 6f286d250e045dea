"""Robot-ticks per second of the three engines, side by side, one core.

Prints one JSON object. Each size runs the same scenario and seeds in the
per-robot reference engine (the per-agent Python baseline, Mesa-style), the
batch engine compiled from the behaviour's own source (jitclasses) and the
struct-of-arrays engine
transformed from the same source (with its cold and warm start in fresh
processes), for a fixed number of ticks (set-up and
compilation excluded from the rates and reported apart; every engine
includes the host coordinators), checks that all end with identical robot
positions, and reports the ratios. "20x500" is 500 independent 20-robot
runs stepped as one batch, the way sweeps use it. (The hand-vectorised
numpy engine this bench also timed until it was retired has its last
side-by-side figures in docs/performance.md.)

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
from sim_backend.batch.compiler import twins  # noqa: E402
from sim_backend.batch.engine import BatchEngine  # noqa: E402
from sim_backend.batch.soa import SoaEngine  # noqa: E402

# robots -> (worldSize, ticks for the reference, ticks for the compiled engines, runs)
SIZES = {
    "20": (18, 400, 400, 1),
    "20x500": (18, 200, 200, 500),
    "1000": (40, 100, 400, 1),
    "10000": (150, 10, 200, 1),
}


def scenario(robots, world):
    return validate({"agents": robots, "worldSize": world, "maxTicks": 10_000_000})


WALL = {}      # (engine, size) -> wall seconds of the timed steps


def timed():
    """(CPU, wall) clocks now."""
    return time.process_time(), time.perf_counter()


def since(t, key):
    """CPU seconds since `t` (from timed()); the wall seconds go to WALL[key]."""
    c, w = timed()
    WALL[key] = round(w - t[1], 4)
    return c - t[0]


def time_reference(sc, seeds, ticks):
    engines = [Engine(sc, s) for s in seeds]
    t0 = timed()
    for e in engines:
        for _ in range(ticks):
            e.step()
    dt = since(t0, ("reference", sc.agents, len(seeds)))
    return dt, [(list(e.world.xs), list(e.world.ys)) for e in engines]


def time_batch(sc, seeds, ticks, engine=BatchEngine):
    t0 = time.perf_counter()
    be = engine([(sc, s) for s in seeds])
    be.step()                      # the first tick compiles the step function
    setup = time.perf_counter() - t0
    t0 = timed()
    for _ in range(ticks - 1):
        be.step()
    dt = since(t0, (engine.__name__, sc.agents, len(seeds)))
    out = []
    for r in range(len(seeds)):
        if not be.rt[B.LIVE, r]:   # delivered early, the reference steps on
            out.append(None)
            continue
        a, b = int(be.rt[B.LO, r]), int(be.rt[B.HI, r])
        out.append((be.rb[B.XS, a:b].tolist(), be.rb[B.YS, a:b].tolist()))
    return dt * ticks / (ticks - 1), out, setup


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
    t0 = time.perf_counter()
    BatchEngine([(scenario(20, 18), 1)]).step()
    res["batch_cold_start_s"] = round(time.perf_counter() - t0, 2)
    res["batch_compile_s"] = round(twins().compile_seconds, 2)
    SoaEngine([(scenario(20, 18), 1)]).step()      # this process's SoA (cache as it is)
    for name, (world, rt, vt, runs) in SIZES.items():
        robots = int(name.split("x")[0])
        if quick:
            rt, vt = max(2, rt // 10), max(2, vt // 10)
        sc = scenario(robots, world)
        seeds = list(range(1, runs + 1))
        ticks = min(rt, vt)
        # same tick count for the identity check, then each engine's own length
        ref_dt, ref_pos = time_reference(sc, seeds, ticks)
        bat_dt, bat_pos, bat_setup = time_batch(sc, seeds, vt)
        soa_dt, soa_pos, soa_setup = time_batch(sc, seeds, vt, SoaEngine)
        # the timed runs' wall seconds (the identity re-runs below overwrite them)
        wall = {k[0]: v for k, v in WALL.items() if k[1:] == (robots, runs)}
        if vt != ticks:
            _, bat_pos, _ = time_batch(sc, seeds, ticks)
            _, soa_pos, _ = time_batch(sc, seeds, ticks, SoaEngine)
        n = robots * runs
        ref_rate = n * ticks / ref_dt
        res["sizes"][name] = {
            "robots": robots, "runs": runs, "worldSize": world,
            "reference": {"ticks": ticks, "seconds": round(ref_dt, 4),
                          "robot_ticks_per_s": round(ref_rate)},
            "batch": {"ticks": vt, "seconds": round(bat_dt, 4), "setup_s": round(bat_setup, 3),
                      "robot_ticks_per_s": round(n * vt / bat_dt)},
            "soa": {"ticks": vt, "seconds": round(soa_dt, 4), "setup_s": round(soa_setup, 3),
                    "robot_ticks_per_s": round(n * vt / soa_dt)},
            "ratio_soa_to_reference": round(n * vt / soa_dt / ref_rate, 2),
            "ratio_soa_to_batch": round(bat_dt / soa_dt, 2),
            "ratio_batch_to_reference": round(n * vt / bat_dt / ref_rate, 2),
            "wall_s": wall,
            "identical_positions": all(b is None or b == r for r, b in zip(ref_pos, bat_pos))
            and all(b is None or b == r for r, b in zip(ref_pos, soa_pos)),
        }
    print(json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
