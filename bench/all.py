"""Every speed figure in one JSON object (`make bench`): the
soa engine against the Mesa 3 port in robot-ticks per CPU second, live
ticks only (bench/mesa_baseline.py), the wall clock a user waits for a
sweep against the same Mesa port and for `touchswarm run` against its floor
(bench/sweep_wall.py), and the command line's start-up (bench/cli_startup.py),
each run in its own interpreter in quick form, then merged; "targets" puts
every ratio beside the figure it should reach.

    .venv/bin/python bench/all.py [--full] [--skip-fresh]

--full: mesa_baseline.py's full cases (20 seeds, 60 Mesa runs beside the
500-run batch, longer big runs) and 3 repetitions of the wall clocks;
without it a few minutes on two cores. --skip-fresh: no sweep on an empty
cache (it starts a compile of several minutes, ended when the sweep is
done). Nothing here is asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

BENCH = Path(__file__).resolve().parent


def piece(script: str, *args: str) -> dict:
    """The JSON object a bench script prints."""
    p = subprocess.run([sys.executable, str(BENCH / script), *args], cwd=BENCH.parent,
                       capture_output=True, text=True)
    if p.returncode != 0:
        return {"error": (p.stderr.strip().splitlines() or ["exit %d" % p.returncode])[-1]}
    return json.loads(p.stdout)


def targets(mesa: dict, wall: dict) -> dict:
    """Each speed ratio and its target."""
    out = {}
    for act, cases in mesa.get("cases", {}).items():
        for name, case in cases.items():
            goal = {"20 robots x 500 runs": 50, "1000 robots": 50, "10000 robots": 100}.get(name)
            out[f"soa/Mesa robot-ticks per CPU s, {name}, {act}"] = {
                "ratio": case["ratio"], **({"target": f">= {goal}"} if goal else {})}
    for key, ratio in (("fresh_sweep", "sweep_over_mesa"), ("fresh_sweep", "sweep_over_mesa_cpu"),
                       ("sweep_500", "speedup_one_process"), ("sweep_500", "speedup_cpu"),
                       ("run", "over_floor")):
        if key in wall:
            out[f"{key}: {ratio}"] = {"ratio": wall[key][ratio], "target": wall[key]["target"]}
    if "sweep_500" in wall:
        out["sweep_500: speedup_per_worker"] = {"ratio": wall["sweep_500"]["speedup_per_worker"],
                                                "target": ">= 10"}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--full", action="store_true", help="the long form of every piece")
    ap.add_argument("--skip-fresh", action="store_true", help="no sweep on an empty cache")
    a = ap.parse_args(argv)
    load = os.getloadavg()[0]
    mesa = piece("mesa_baseline.py", *([] if a.full else ["--quick", "--batch-runs", "500"]))
    wall = piece("sweep_wall.py", *(["--reps", "3", "--mesa-runs", "100"] if a.full else []),
                 *(["--skip-fresh"] if a.skip_fresh else []))
    startup = piece("cli_startup.py", "--reps", "5" if a.full else "3")
    out = {"cpus": os.cpu_count(), "load_avg_before": load, "form": "full" if a.full else "quick",
           "targets": targets(mesa, wall), "mesa_baseline": mesa, "wall": wall,
           "startup": startup, "load_avg_after": os.getloadavg()[0]}
    print(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
