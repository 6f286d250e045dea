"""Run records equivalent to the thesis's output files.

indstats.csv  one row per touch (the thesis wrote each finder's time)
shape.csv     the finders' rounded coordinates, leader marked (shape.txt)
ct.csv        convergence tick: power reached the object's weight (ct.txt)
tt.csv        transport tick: the object reached home (tt.txt)
summary.json  the run's summary, as `touchswarm run --json` prints it
"""

from __future__ import annotations

import csv
import json
from pathlib import Path

from sim_backend.engine import RunResult


def write_records(result: RunResult, out: Path) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    c = result.coordinator
    paths = []

    def table(name: str, header: list[str], rows: list[list]) -> None:
        p = out / name
        with p.open("w", newline="") as f:
            wr = csv.writer(f, lineterminator="\n")
            wr.writerow(header)
            wr.writerows(rows)
        paths.append(p)

    table("indstats.csv", ["seed", "node", "tick", "rx", "ry", "sx", "sy", "power"],
          [[result.seed, t.node, t.tick, t.rx, t.ry, t.sx, t.sy, t.power / 100]
           for t in c.touches])
    table("shape.csv", ["seed", "x", "y", "leader"],
          [[result.seed, t.rx, t.ry, int(t.node == c.leader)] for t in c.touches])
    table("ct.csv", ["seed", "converged_tick"],
          [[result.seed, c.converged_tick if c.converged_tick >= 0 else ""]])
    table("tt.csv", ["seed", "home_tick"],
          [[result.seed, c.delivered_tick if c.delivered_tick >= 0 else ""]])
    p = out / "summary.json"
    p.write_text(json.dumps(result.summary(), sort_keys=True, indent=2) + "\n")
    paths.append(p)
    return paths
