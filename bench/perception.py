"""The new shape estimate and recognition against the thesis's hull
(docs/perception.md): for every built-in object, 20 seeds,
runs with objectWeight 12 (so the swarm keeps touching until 12 robots hold
it); the host's view is taken as each touch arrives (k = 1..12), which is the
view at convergence of a run whose weight is k (before convergence the
weight changes nothing). Several perceivers watch the same run, one per
free-evidence rate: every tick (the simulation's full view), every 8 ticks,
every 64 ticks (today's search HEARTBEAT), never (touches only).

Writes DIR/perception.csv (one row per object, seed, rate, k), DIR/table.md,
the figures DIR/perception_iou.png, DIR/perception_accuracy.png and
DIR/perception_shapes.png; prints JSON (the table and the wall time).

    .venv/bin/python bench/perception.py [--seeds 20] [--out perception-out]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from perception.tracker import Perceiver  # noqa: E402
from sim_backend import objects, scenario  # noqa: E402
from sim_backend.engine import Engine  # noqa: E402

HOLDERS = 12
RATES = (1, 8, 64, 0)          # free evidence every N ticks; 0: never
TABLE_K = (4, 8, 12)
MAX_TICKS = 5000


def one(job: tuple[str, int]) -> list[dict]:
    obj, seed = job
    sc = scenario.load("default").replace(object=obj, objectWeight=float(HOLDERS),
                                          maxTicks=MAX_TICKS)
    e = Engine(sc, seed)
    ps = {r: Perceiver(e, free_every=r, watch=False) for r in RATES}
    while e.coordinator.converged_tick < 0 and e.tick < MAX_TICKS:
        e.step()
        for p in ps.values():
            p.update()
    rows = []
    for rate, p in ps.items():
        for k, a in sorted(p.by_touches.items()):
            if k > HOLDERS:
                break
            rows.append({"object": obj, "seed": seed, "free_every": rate, "k": k,
                         "tick": a.tick, "estimate_iou": a.estimate_iou,
                         "hull_free_iou": a.hull_free_iou, "hull_iou": a.hull_iou,
                         "best": a.best, "p": round(a.p, 6),
                         "recognised_tick": p.recognised_tick if p.recognised_tick is not None
                         and p.recognised_tick <= a.tick else "",
                         "recognised_as": p.recognised_as if p.recognised_tick is not None
                         and p.recognised_tick <= a.tick else ""})
    return rows


def mean(v: list[float]) -> float:
    return sum(v) / len(v) if v else float("nan")


def summarise(rows: list[dict]) -> dict:
    """{rate: {object: {k: {...}}}}: mean IoUs, recognition accuracy, counts."""
    out: dict = {}
    for r in rows:
        d = out.setdefault(r["free_every"], {}).setdefault(r["object"], {}).setdefault(r["k"], [])
        d.append(r)
    table: dict = {}
    for rate, objs in out.items():
        for obj, ks in objs.items():
            for k, rs in ks.items():
                table.setdefault(rate, {}).setdefault(obj, {})[k] = {
                    "n": len(rs),
                    "estimate_iou": mean([x["estimate_iou"] for x in rs]),
                    "hull_free_iou": mean([x["hull_free_iou"] for x in rs]),
                    "hull_iou": mean([x["hull_iou"] for x in rs]),
                    "top1": mean([x["best"] == obj for x in rs]),
                    "recognised_right": mean([x["recognised_as"] == obj for x in rs]),
                    "recognised_wrong": mean([x["recognised_as"] not in ("", obj) for x in rs]),
                }
    return table


def markdown(table: dict, seeds: int) -> str:
    lines = []
    for rate in RATES:
        t = table.get(rate, {})
        label = {1: "every tick", 8: "every 8 ticks", 64: "every 64 ticks (today's HEARTBEAT)",
                 0: "none (touches only)"}[rate]
        lines += [f"Free evidence: {label}; mean over {seeds} seeds (runs that reached k holders).",
                  "", "| object | " + " | ".join(
                      f"k={k}: estimate / hull-free / thesis hull / recognised right, wrong"
                      for k in TABLE_K) + " |",
                  "|---|" + "---|" * len(TABLE_K)]
        for obj in objects.SHAPES:
            cells = []
            for k in TABLE_K:
                c = t.get(obj, {}).get(k)
                cells.append("-" if c is None else
                             f"{c['estimate_iou']:.2f} / {c['hull_free_iou']:.2f} / "
                             f"{c['hull_iou']:.2f} / {c['recognised_right']:.2f}, "
                             f"{c['recognised_wrong']:.2f} (n={c['n']})")
            lines.append(f"| {obj} | " + " | ".join(cells) + " |")
        lines.append("")
    return "\n".join(lines)


def figures(table: dict, out: Path) -> list[Path]:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    ks = list(range(1, HOLDERS + 1))
    names = list(objects.SHAPES)
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5), sharey=True)
    for ax, key, title in zip(axes, ("estimate_iou", "hull_free_iou", "hull_iou"),
                              ("new estimate (MAP if recognised, else hull - free)",
                               "hull minus known-free cells (no library)",
                               "thesis view: hull of the touched segments")):
        for obj in names:
            d = table[1].get(obj, {})
            ax.plot([k for k in ks if k in d], [d[k][key] for k in ks if k in d],
                    marker="o", ms=3, label=obj)
        ax.axhline(0.8, color="grey", lw=0.8, ls="--")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("robots holding (touches)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("mean IoU with the true shape")
    axes[0].legend(fontsize=8)
    fig.suptitle("Shape estimate vs holders (free evidence every tick)")
    fig.tight_layout()
    p1 = out / "perception_iou.png"
    fig.savefig(p1, dpi=110)
    plt.close(fig)
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.5), sharey=True)
    for obj in names:
        d = table[1].get(obj, {})
        axes[0].plot([k for k in ks if k in d], [d[k]["recognised_right"] for k in ks if k in d],
                     marker="o", ms=3, label=obj)
    for rate in RATES:
        t = table.get(rate, {})
        ys = [mean([t[o][k]["recognised_right"] for o in names if k in t.get(o, {})])
              for k in ks]
        axes[1].plot(ks, ys, marker="o", ms=3, label=f"free every {rate}" if rate else
                     "touches only")
    axes[0].set_title("recognised (p >= 0.95) and right, per object\n(free evidence every tick)",
                      fontsize=10)
    axes[1].set_title("recognised and right, mean over objects,\nby free-evidence rate",
                      fontsize=10)
    for ax in axes:
        ax.set_xlabel("touches")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    axes[0].set_ylabel("fraction of runs")
    fig.tight_layout()
    p2 = out / "perception_accuracy.png"
    fig.savefig(p2, dpi=110)
    plt.close(fig)
    return [p1, p2, shapes_figure(out, plt)]


def shapes_figure(out: Path, plt) -> Path:
    """Figures 22-24 redrawn: for each thesis object (seed 1, 12 holders) the
    truth, the thesis's hull and the new estimate, with the evidence."""
    thesis = [objects.THESIS_NUMBERS[i] for i in sorted(objects.THESIS_NUMBERS)]
    fig, axes = plt.subplots(2, len(thesis), figsize=(4 * len(thesis), 8))
    for j, obj in enumerate(thesis):
        sc = scenario.load("default").replace(object=obj, objectWeight=float(HOLDERS),
                                              maxTicks=MAX_TICKS)
        e = Engine(sc, 1)
        p = Perceiver(e, watch=False)
        while e.coordinator.converged_tick < 0 and e.tick < MAX_TICKS:
            e.step()
            p.update()
        s = p.summary()
        truth, free = p.truth, p.ev.free_set()
        xs = [c[0] for c in truth]
        ys = [c[1] for c in truth]
        box = (min(xs) - 3, max(xs) + 3, min(ys) - 3, max(ys) + 3)
        hull = p.ev.hull_cells()
        for i, (cells, title) in enumerate(
                ((hull, f"{obj}: thesis view (hull of touches), IoU {_iou(hull, truth):.2f}"),
                 (p.est, f"{obj}: new estimate ({s['estimate_kind']}), IoU "
                         f"{s['estimate_iou']:.2f}"))):
            ax = axes[i][j]
            for (x, y) in truth:
                ax.add_patch(plt.Rectangle((x - .5, y - .5), 1, 1, color="gold", alpha=.6))
            for (x, y) in cells:
                ax.add_patch(plt.Rectangle((x - .5, y - .5), 1, 1, fill=False, ec="tab:blue",
                                           lw=1.5))
            fx_ = [c for c in free if box[0] <= c[0] <= box[1] and box[2] <= c[1] <= box[3]]
            ax.plot([c[0] for c in fx_], [c[1] for c in fx_], ".", color="grey", ms=3)
            ax.plot([c[0] for c in p.ev.touched], [c[1] for c in p.ev.touched], "x", color="k")
            ax.set_xlim(box[0], box[1])
            ax.set_ylim(box[2], box[3])
            ax.set_aspect("equal")
            ax.set_title(title, fontsize=9)
    fig.suptitle("Figures 22-24 redrawn (seed 1, 12 holders): truth yellow, estimate blue, "
                 "touches x, cells seen free grey dots", fontsize=10)
    fig.tight_layout()
    path = out / "perception_shapes.png"
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _iou(a, b) -> float:
    from perception.evidence import iou
    return iou(a, b)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--out", type=Path, default=Path("perception-out"))
    ap.add_argument("--objects", default=",".join(objects.SHAPES),
                    help="comma-separated built-in objects (default: all)")
    a = ap.parse_args()
    objs = [o for o in a.objects.split(",") if o]
    bad = [o for o in objs if o not in objects.SHAPES]
    if bad or a.seeds < 1 or a.workers < 1:
        sys.exit(f"perception.py: error: bad --objects {bad} / --seeds / --workers")
    a.out.mkdir(parents=True, exist_ok=True)
    jobs = [(o, s) for o in objs for s in range(1, a.seeds + 1)]
    t0 = time.perf_counter()
    rows: list[dict] = []
    with ProcessPoolExecutor(a.workers) as ex:
        for rs in ex.map(one, jobs):
            rows += rs
    wall = time.perf_counter() - t0
    with (a.out / "perception.csv").open("w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=list(rows[0]))
        wr.writeheader()
        wr.writerows(rows)
    table = summarise(rows)
    (a.out / "table.md").write_text(markdown(table, a.seeds))
    pngs = figures(table, a.out)
    print(json.dumps({"runs": len(jobs), "wall_s": round(wall, 1), "seeds": a.seeds,
                      "figures": [str(p) for p in pngs],
                      "table": {str(r): {o: {str(k): {n: round(v, 3) for n, v in c.items()}
                                             for k, c in d.items() if k in TABLE_K}
                                         for o, d in t.items()}
                                for r, t in table.items()}}, indent=1))


if __name__ == "__main__":
    main()
