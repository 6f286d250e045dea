"""The world's preset sweeps (`touchswarm sweep --preset sizes|obstacles|field`) and
their figures: per point the delivery rate, the median tick of delivery and
the mean IoU of the perceived shape (docs/extensions.md).

bench/arena_sweeps.py runs the same points with a JSON summary per preset.
"""

from __future__ import annotations

import math
import statistics
from pathlib import Path
from typing import Any, Sequence

from sim_backend.plots import _delivered, _save
from sim_backend.robustness import _num
from sim_backend.sweep import Point

SEEDS = 10
MAX_TICKS = 6000

# the default arena: 20 robots in 37 x 37 patches (worldSize 18)
DENSITY = 20 / 37 ** 2
SMALL_SIZES = (20, 50, 100, 200, 300)      # in the default arena
LARGE_SIZES = (1000, 10000)                # in arenas scaled to the same density


def scaled_world(agents: int) -> int:
    """The worldSize whose (2w + 1)^2 patches hold `agents` at DENSITY."""
    return math.ceil((math.sqrt(agents / DENSITY) - 1) / 2)


def size_points() -> list[Point]:
    pts = [Point("sizes", (("agents", a),)) for a in SMALL_SIZES]
    pts += [Point("sizes", (("agents", a), ("worldSize", scaled_world(a))))
            for a in LARGE_SIZES]
    return pts


def obstacle_points() -> list[Point]:
    """The built-in `wall` scenario with its wall, and without."""
    from sim_backend.scenario import load
    wall = load("wall").obstacles
    return [Point("obstacles", (("obstacles", wall),)), Point("obstacles", (("obstacles", ()),))]


def field_points() -> list[Point]:
    return [Point("field", (("agents", a), ("field", f), ("crowd", c)))
            for a, c in ((20, "block"), (20, "yield"), (100, "yield"), (300, "yield"))
            for f in ("static", "dynamic")]


# name -> (base scenario, points); every preset runs until delivered
PRESETS = {"sizes": ("default", size_points), "obstacles": ("wall", obstacle_points),
           "field": ("default", field_points)}


def label(params: str) -> str:
    """A point's `k=v;k=v` text as the figure's label (obstacles on or off)."""
    out = []
    for kv in params.split(";"):
        k, _, v = kv.partition("=")
        out.append(f"obstacles={'off' if v in ('()', '') else 'on'}" if k == "obstacles"
                   else kv)
    return ", ".join(out)


def summarise(rows: Sequence[dict]) -> list[dict]:
    """Per point, in the rows' order: runs, delivered, median delivery tick
    (delivered runs), mean IoU."""
    order: list[str] = []
    by: dict[str, list[dict]] = {}
    for r in rows:
        if r["point"] not in by:
            order.append(r["point"])
        by.setdefault(r["point"], []).append(r)
    out = []
    for p in order:
        rs = by[p]
        home = [_num(r["home_tick"]) for r in rs if _delivered(r)]
        ticks = [h for h in home if h is not None]     # a delivered run has its home tick
        ious = [v for v in (_num(r["shape_iou"]) for r in rs) if v is not None]
        out.append({"point": label(p), "n": len(rs), "delivered": len(home),
                    "median_home_tick": statistics.median(ticks) if ticks else None,
                    "mean_iou": round(statistics.fmean(ious), 3) if ious else None})
    return out


def plots(rows: Sequence[dict], out: Path, name: str) -> list[Path]:
    """<name>.png: delivery rate, median ticks to delivery and mean IoU per point."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    summary = summarise(rows)
    if not summary:
        return []
    labels = [s["point"] for s in summary]
    fig, axes = plt.subplots(1, 3, figsize=(13, 1.2 + 0.32 * len(labels)), sharey=True)
    y = list(range(len(labels)))[::-1]
    axes[0].barh(y, [s["delivered"] / s["n"] for s in summary], color="tab:green")
    axes[0].set_xlim(0, 1)
    axes[0].set_title("delivery rate")
    for yy, s in zip(y, summary):
        axes[0].text(0.02, yy, f"{s['delivered']}/{s['n']}", va="center", fontsize=8)
    axes[1].barh(y, [s["median_home_tick"] or 0 for s in summary], color="tab:blue")
    axes[1].set_title("median ticks to delivery (delivered runs)")
    axes[2].barh(y, [s["mean_iou"] or 0 for s in summary], color="tab:orange")
    for yy, s in zip(y, summary):
        if s["mean_iou"] is None:
            axes[2].text(0.02, yy, "n/a", va="center", fontsize=8)
    axes[2].set_xlim(0, 1)
    axes[2].set_title("mean IoU of the perceived shape")
    axes[0].set_yticks(y)
    axes[0].set_yticklabels(labels, fontsize=8)
    runs = sorted({s["n"] for s in summary})
    fig.suptitle(f"{name}: {'/'.join(map(str, runs))} seeds per point "
                 f"(touchswarm sweep --preset {name})")
    fig.tight_layout()
    return [_save(fig, out / f"{name}.png", dpi=90)]


def table(rows: Sequence[dict]) -> list[str]:
    """The summary as markdown rows (docs/extensions.md)."""
    lines = ["| point | delivered | median ticks to delivery | mean IoU |", "|---|---|---|---|"]
    for s in summarise(rows):
        lines.append(f"| {s['point']} | {s['delivered']}/{s['n']} | "
                     f"{s['median_home_tick'] if s['median_home_tick'] is not None else '-'} | "
                     f"{s['mean_iou']} |")
    return lines


def main(argv: Sequence[str] | None = None) -> Any:
    """`python -m sim_backend.arena_presets NAME SWEEP_CSV`: the markdown table."""
    import sys
    from sim_backend.sweep import read_csv
    args = list(sys.argv[1:] if argv is None else argv)
    print("\n".join(table(read_csv(Path(args[1])))))


if __name__ == "__main__":
    main()
