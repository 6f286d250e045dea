"""Run records equivalent to the thesis's output files.

indstats.csv  one row per touch (the thesis wrote each finder's time); the
              finder's power for a behaviour that declares a load (LOAD)
shape.csv     the finders' rounded coordinates, leader marked (shape.txt);
              for a behaviour that perceives a shape (SHAPE)
ct.csv        convergence tick: power reached the object's weight (ct.txt);
              for a behaviour that declares a load
tt.csv        transport tick: the object reached home (tt.txt); every
              behaviour's delivered tick
summary.json  the run's summary, as `touchswarm run --json` prints it

A behaviour's words (sim_backend/words.py) say which apply: a behaviour
that carries no load and perceives no shape gets no power, leader or
convergence written in its name.
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

    from sim_backend import registry, words
    w = words.of(registry.load(result.scenario.behaviour))
    load = ["power"] if w.load else []
    table("indstats.csv", ["seed", "node", "tick", "rx", "ry", "sx", "sy", *load],
          [[result.seed, t.node, t.tick, t.rx, t.ry, t.sx, t.sy] + ([t.power / 100] if load
                                                                    else [])
           for t in c.touches])
    if w.shape:
        table("shape.csv", ["seed", "x", "y", "leader"],
              [[result.seed, t.rx, t.ry, int(t.node == c.leader)] for t in c.touches])
    if w.load:
        table("ct.csv", ["seed", "converged_tick"],
              [[result.seed, c.converged_tick if c.converged_tick >= 0 else ""]])
    table("tt.csv", ["seed", "home_tick"],
          [[result.seed, c.delivered_tick if c.delivered_tick >= 0 else ""]])
    p = out / "summary.json"
    p.write_text(json.dumps(result.summary(), sort_keys=True, indent=2) + "\n")
    paths.append(p)
    return paths
