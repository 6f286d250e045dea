"""The sweeps of docs/extensions.md for issue 11: obstacles on and off, the
static and the dynamic field, and swarm size with a crowd that blocks or
yields. Each writes its rows to OUT/<name>.csv and a figure (delivery rate,
time to delivery, IoU per point) to OUT/<name>.png; one JSON line per
experiment on stdout and in OUT/<name>.json.

    .venv/bin/python bench/arena_sweeps.py [--seeds 10] [--out arena-out]
        [--only obstacles,field,size,large] [--replot OUT/size.json ...]
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from pathlib import Path

from sim_backend.scenario import load, validate
from sim_backend.sweep import Point, sweep, write_csv


def experiments() -> dict[str, tuple]:
    """name -> (base scenario, points, maxTicks)."""
    wall = load("wall")
    default = validate({})
    return {
        "obstacles": (wall, [Point("obstacles", (("obstacles", wall.obstacles),)),
                             Point("obstacles", (("obstacles", ()),))], 6000),
        "field": (default, [Point("field", (("agents", a), ("field", f), ("crowd", c)))
                            for a, c in ((20, "block"), (20, "yield"), (100, "yield"),
                                         (300, "yield"))
                            for f in ("static", "dynamic")], 6000),
        "size": (default, [Point("size", (("agents", a), ("crowd", c)))
                           for a in (20, 50, 100, 150, 200, 300)
                           for c in ("block", "yield")], 6000),
        # 1,000 robots at the default density (20 in 37 x 37): worldSize 130
        "large": (default, [Point("large", (("agents", 1000), ("worldSize", 130),
                                            ("crowd", c))) for c in ("block", "yield")],
                  6000),
    }


def label(pt: Point) -> str:
    out = []
    for k, v in pt.params:
        out.append(f"{k}={'on' if v else 'off'}" if k == "obstacles" else f"{k}={v}")
    return ", ".join(out)


def summarise(rows: list[dict], points: list[Point]) -> list[dict]:
    out = []
    for pt in points:
        key = ";".join(f"{k}={v}" for k, v in pt.params)
        rs = [r for r in rows if r["point"] == key]
        home = [r["home_tick"] for r in rs if r["delivered"]]
        out.append({"point": label(pt), "n": len(rs),
                    "delivered": sum(1 for r in rs if r["delivered"]),
                    "median_home_tick": statistics.median(home) if home else None,
                    "mean_iou": round(statistics.fmean(r["shape_iou"] for r in rs), 3),
                    "outcomes": {o: sum(1 for r in rs if r.get("outcome") == o)
                                 for o in sorted({r.get("outcome") for r in rs})}})
    return out


def figure(name: str, summary: list[dict], path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    labels = [s["point"] for s in summary]
    fig, axes = plt.subplots(1, 3, figsize=(13, 1.2 + 0.32 * len(labels)), sharey=True)
    y = list(range(len(labels)))[::-1]
    rate = [s["delivered"] / s["n"] for s in summary]
    axes[0].barh(y, rate, color="tab:green")
    axes[0].set_xlim(0, 1)
    axes[0].set_title("delivery rate")
    for yy, s in zip(y, summary):
        axes[0].text(0.02, yy, f"{s['delivered']}/{s['n']}", va="center", fontsize=8)
    axes[1].barh(y, [s["median_home_tick"] or 0 for s in summary], color="tab:blue")
    axes[1].set_title("median ticks to delivery (delivered runs)")
    axes[2].barh(y, [s["mean_iou"] for s in summary], color="tab:orange")
    axes[2].set_xlim(0, 1)
    axes[2].set_title("mean IoU of the perceived shape")
    axes[0].set_yticks(y)
    axes[0].set_yticklabels(labels, fontsize=8)
    fig.suptitle(f"{name}: n = {summary[0]['n']} seeds per point (batch engine)")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--out", default="arena-out")
    ap.add_argument("--only", default="obstacles,field,size")
    ap.add_argument("--replot", nargs="+", help="redraw the figures from these JSON files")
    args = ap.parse_args()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.replot:
        for f in args.replot:
            for line in Path(f).read_text().splitlines():
                d = json.loads(line)
                figure(d["experiment"], d["points"], out / f"{d['experiment']}.png")
        return
    exps = experiments()
    for name in args.only.split(","):
        base, points, max_ticks = exps[name]
        t0 = time.perf_counter()
        rows = sweep(points, range(1, args.seeds + 1), base=base, engine="batch",
                     overrides={"maxTicks": max_ticks})
        write_csv(rows, out / f"{name}.csv")
        summary = summarise(rows, points)
        figure(name, summary, out / f"{name}.png")
        line = json.dumps({"experiment": name, "seeds": args.seeds, "maxTicks": max_ticks,
                           "wall_s": round(time.perf_counter() - t0, 1), "points": summary})
        (out / f"{name}.json").write_text(line + "\n")
        print(line, flush=True)


if __name__ == "__main__":
    main()
