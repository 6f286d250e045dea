"""Robot-ticks per second of the reference and the vectorised engine, one core.

Prints one JSON object. Each size runs the same scenario and seed in both
engines for a fixed number of ticks (the vectorised engine's set-up is
excluded, as is the reference's; both include the host coordinator), checks
that both end with identical robot positions, and reports the ratio. "20x500"
is 500 independent 20-robot runs stepped as one batch, the way sweeps use it.

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
from sim_backend.vector_engine import VectorEngine  # noqa: E402

# robots -> (worldSize, ticks for the reference, ticks for the vector engine, runs)
SIZES = {
    "20": (18, 400, 400, 1),
    "20x500": (18, 200, 200, 500),
    "1000": (40, 100, 400, 1),
    "10000": (150, 10, 200, 1),
}


def scenario(robots, world):
    return validate({"agents": robots, "worldSize": world, "maxTicks": 10_000_000})


def time_reference(sc, seeds, ticks):
    engines = [Engine(sc, s) for s in seeds]
    t0 = time.perf_counter()
    for e in engines:
        for _ in range(ticks):
            e.step()
    dt = time.perf_counter() - t0
    return dt, [(list(e.world.xs), list(e.world.ys)) for e in engines]


def time_vector(sc, seeds, ticks):
    ve = VectorEngine([(sc, s) for s in seeds])
    t0 = time.perf_counter()
    for _ in range(ticks):
        ve.step()
    dt = time.perf_counter() - t0
    out = []
    for r in range(len(seeds)):
        if not ve.alive[r]:          # delivered early: the reference steps on, we stop
            out.append(None)
            continue
        a = int(ve.run_start[r])
        out.append((ve.x[a:a + sc.agents].tolist(), ve.y[a:a + sc.agents].tolist()))
    return dt, out


def main():
    quick = "--quick" in sys.argv
    res = {"cores": 1, "sizes": {}}
    for name, (world, rt, vt, runs) in SIZES.items():
        robots = int(name.split("x")[0])
        if quick:
            rt, vt = max(2, rt // 10), max(2, vt // 10)
        sc = scenario(robots, world)
        seeds = list(range(1, runs + 1))
        ticks = min(rt, vt)
        # same tick count for the identity check, then each engine's own length
        ref_dt, ref_pos = time_reference(sc, seeds, ticks)
        vec_dt_same, vec_pos = time_vector(sc, seeds, ticks)
        vec_dt, _ = time_vector(sc, seeds, vt) if vt != ticks else (vec_dt_same, None)
        n = robots * runs
        ref_rate = n * ticks / ref_dt
        vec_rate = n * vt / vec_dt
        res["sizes"][name] = {
            "robots": robots, "runs": runs, "worldSize": world,
            "reference": {"ticks": ticks, "seconds": round(ref_dt, 4),
                          "robot_ticks_per_s": round(ref_rate)},
            "vector": {"ticks": vt, "seconds": round(vec_dt, 4),
                       "robot_ticks_per_s": round(vec_rate)},
            "ratio": round(vec_rate / ref_rate, 2),
            "identical_positions": all(v is None or v == r for r, v in zip(ref_pos, vec_pos)),
        }
    print(json.dumps(res, indent=2))


if __name__ == "__main__":
    main()
