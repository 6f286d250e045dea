"""The host's decision by recognition (docs/perception.md "The
decision"): every built-in shape as the target beside the diagonal decoy of
the built-in `decoy` scenario, `recognise = true`, seeds 1..N, reference
engine. Accuracy against touches: whenever the host accepts a touch on an
object before the transport, the bench asks the run's decider about that
object's first k touches (every touch on it so far, released ones too, with
the free cells the host had seen by then) and logs the verdict beside the
truth. (The coordinator's own questions are not used for this: it stops
asking about a cluster once decided, so its late questions are about the
hard cases only.)

Writes DIR/recognition_runs.csv (one row per run: the summary's decision
fields), DIR/recognition_verdicts.csv (one row per object and touch), the figure
DIR/recognition.png; prints JSON (per shape: runs, delivered, wrong
transports, decoy releases, median target tick and confidence; accuracy by
touches) and the wall time.

    .venv/bin/python bench/recognition.py [--seeds 10] [--workers 2] [--out recognition-out]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import statistics
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from firmware_logic import messages as msg  # noqa: E402
from sim_backend import objects, scenario  # noqa: E402
from sim_backend.engine import Engine  # noqa: E402

MAX_TICKS = 5000
MAX_K = 10          # touches on an object counted in the accuracy table
MIN_N = 3           # verdicts a point of the accuracy figure needs


def scenario_for(shape: str) -> scenario.Scenario:
    """The built-in decoy scenario with `shape` as the target."""
    return scenario.validate({
        "name": f"decoy-{shape}", "agents": 20, "recognise": True, "maxTicks": MAX_TICKS,
        "objects": [
            {"name": shape, "shape": shape, "at": [3, 4], "weight": 5.0, "target": True},
            {"name": "decoy", "cells": [[0, 0], [1, 1], [2, 2], [3, 3]], "at": [-12, 6],
             "target": False}]}, f"bench {shape}")


def one(job: tuple[str, int]) -> tuple[dict, list[dict]]:
    shape, seed = job
    sc = scenario_for(shape)
    e = Engine(sc, seed)
    c = e.coordinator
    truth = {cell: ("target" if j == 0 else "decoy")
             for j, p in enumerate(sc.pieces()) for cell in p.placed(*p.at)}
    conf = round(sc.confidence * 1000)
    log: list[dict] = []
    seen: dict[str, list] = {"target": [], "decoy": []}

    def journal(node, kind, f, tick):
        if kind != msg.TOUCH or c.converged_tick >= 0:
            return
        obj = truth.get((f[3], f[4]))
        if obj is None:
            return
        cells = seen[obj]
        cells.append((f[3], f[4]))
        p = c.decider(list(cells), dict(c.free_seen))
        verdict = "target" if p >= conf else "decoy" if 1000 - p >= conf else "undecided"
        log.append({"shape": shape, "seed": seed, "tick": tick, "k": len(cells),
                    "truth": obj, "permille": p, "verdict": verdict})
    c.journal = journal
    s = e.run().summary()
    run = {"shape": shape, "seed": seed, "ticks": s["ticks"], "delivered": s["delivered"],
           "target_tick": s["target_tick"], "target_permille": s["target_permille"],
           "converged_tick": s["converged_tick"], "releases": s["releases"],
           "wrong_transport": s["wrong_transport"], "outcome": s["outcome"]}
    return run, log


def summarise(runs: list[dict], verdicts: list[dict]) -> dict:
    out: dict = {}
    for shape in objects.SHAPES:
        rs = [r for r in runs if r["shape"] == shape]
        ticks = [r["target_tick"] for r in rs if r["target_tick"] is not None]
        ps = [r["target_permille"] for r in rs if r["target_permille"] is not None]
        acc = {}
        for truth in ("target", "decoy"):
            by_k = {}
            for k in range(1, MAX_K + 1):
                vs = [v for v in verdicts if v["shape"] == shape and v["truth"] == truth
                      and v["k"] == k]
                if vs:
                    by_k[k] = {"n": len(vs),
                               "right": round(sum(v["verdict"] == truth for v in vs) / len(vs), 3),
                               "wrong": round(sum(v["verdict"] not in (truth, "undecided")
                                                  for v in vs) / len(vs), 3)}
            acc[truth] = by_k
        out[shape] = {"runs": len(rs), "delivered": sum(r["delivered"] for r in rs),
                      "wrong_transports": sum(bool(r["wrong_transport"]) for r in rs),
                      "releases": sum(r["releases"] for r in rs),
                      "median_target_tick": statistics.median(ticks) if ticks else None,
                      "median_target_permille": statistics.median(ps) if ps else None,
                      "accuracy": acc}
    return out


def figure(table: dict, out: Path) -> Path:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sim_backend.plots import _save
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.4))
    for ax, truth, title in ((axes[0], "target", "the target: called the target"),
                             (axes[1], "decoy", "the decoy: called a decoy")):
        for shape, row in table.items():
            acc = {int(k): v for k, v in row["accuracy"][truth].items() if v["n"] >= MIN_N}
            ks = sorted(acc)
            ax.plot(ks, [acc[k]["right"] for k in ks], marker="o", label=shape)
            bad = [k for k in ks if acc[k]["wrong"] > 0]
            ax.plot(bad, [acc[k]["wrong"] for k in bad], "x", color="red")
        ax.set_xlabel("touches on the object (k-th touch)")
        ax.set_ylabel(f"share of runs right (red x: wrong; >= {MIN_N} runs)")
        ax.set_ylim(-0.02, 1.02)
        ax.set_title(title, fontsize=10)
    axes[0].legend(fontsize=8)
    names = list(table)
    runs = [table[n]["runs"] for n in names]
    wrong = [table[n]["wrong_transports"] for n in names]
    right = [table[n]["delivered"] - w for n, w in zip(names, wrong)]
    lost = [r - d - w for r, d, w in zip(runs, right, wrong)]
    axes[2].bar(names, right, color="tab:green", label="target delivered")
    axes[2].bar(names, wrong, bottom=right, color="red", label="wrong transport (a decoy)")
    axes[2].bar(names, lost, bottom=[a + b for a, b in zip(right, wrong)], color="grey",
                label="not delivered")
    for i, n in enumerate(names):
        axes[2].text(i, runs[i] + 0.2, f"{wrong[i]} wrong", ha="center", fontsize=8)
    axes[2].set_ylim(0, max(runs) * 1.2)
    axes[2].set_ylabel("runs")
    axes[2].set_title("each shape as the target beside the diagonal decoy", fontsize=10)
    axes[2].legend(fontsize=8, loc="lower right")
    fig.tight_layout()
    return _save(fig, out / "recognition.png")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", type=Path, default=Path("recognition-out"))
    a = ap.parse_args()
    if a.seeds < 1 or a.workers < 1:
        ap.error("--seeds and --workers: expected >= 1")
    t0 = time.time()
    jobs = [(shape, seed) for shape in objects.SHAPES for seed in range(1, a.seeds + 1)]
    runs, verdicts = [], []
    with ProcessPoolExecutor(a.workers) as ex:
        for run, log in ex.map(one, jobs):
            runs.append(run)
            verdicts.extend(log)
    a.out.mkdir(parents=True, exist_ok=True)
    for name, rows in (("recognition_runs.csv", runs), ("recognition_verdicts.csv", verdicts)):
        with (a.out / name).open("w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
            w.writeheader()
            w.writerows(rows)
    table = summarise(runs, verdicts)
    fig = figure(table, a.out)
    print(json.dumps({"seeds": a.seeds, "table": table, "figure": str(fig),
                      "wall_s": round(time.time() - t0, 1)}))


if __name__ == "__main__":
    main()
