"""The thesis's own way of showing its results, beside the project's plots
(sim_backend/plots.py), for `touchswarm sweep --thesis` (issue 10 section 3).

- Graph 1 in both units: convergence in go iterations (the thesis's loop;
  under activation sync a tick is one) and in robot moves (FSM steps per
  robot: under activation netlogo a robot in a field takes 1 + fieldDefiance
  per go iteration), since a trend in one need not be a trend in the other.
- Figures 22-24 as the thesis drew them: the rounded positions of the robots
  holding the object (DrawShape's shape.txt) and the polygon through them,
  judged by eye; the IoU of the project's measure is in each panel's title.

Rows are sweep rows (sim_backend/sweep.py) or the same read back from CSV.
"""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path
from typing import Sequence

from sim_backend.plots import SHAPE_FIGURES, _example, _num, _save, _stats


def graph1_table(rows: Sequence[dict]) -> dict:
    """{model: [(fieldDefiance, mean go iterations, sem, mean moves, sem,
    converged, n)]} over the runs that converged."""
    groups: dict[tuple[str, int], list] = defaultdict(list)
    for r in rows:
        if r["experiment"] == "graph1":
            groups[(r["movementModel"], _num(r["fieldDefiance"]))].append(r)
    out: dict[str, list] = defaultdict(list)
    for (model, fd), rs in sorted(groups.items()):
        done = [r for r in rs if _num(r["converged_tick"]) is not None]
        if not done:
            out[model].append((fd, math.nan, 0.0, math.nan, 0.0, 0, len(rs)))
            continue
        it, it_sem, _ = _stats([float(_num(r["converged_tick"])) for r in done])
        mv, mv_sem, _ = _stats([float(_num(r["converged_moves"])) for r in done])
        out[model].append((fd, it, it_sem, mv, mv_sem, len(done), len(rs)))
    return dict(out)


def plot_graph1_units(rows: Sequence[dict], path: Path) -> Path | None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = graph1_table(rows)
    if not table:
        return None
    act = sorted({str(r.get("activation", "sync")) for r in rows if r["experiment"] == "graph1"})
    models = [m for m in ("firefly", "ant") if m in table]
    fig, axes = plt.subplots(1, len(models), figsize=(4.8 * len(models), 3.6), squeeze=False)
    for ax, model in zip(axes[0], models):
        pts = table[model]
        xs = [p[0] for p in pts]
        ax.errorbar(xs, [p[1] for p in pts], yerr=[1.96 * p[2] for p in pts], marker="o",
                    capsize=3, label="go iterations")
        ax.errorbar(xs, [p[3] for p in pts], yerr=[1.96 * p[4] for p in pts], marker="s",
                    capsize=3, label="robot moves")
        stalled = [p[6] - p[5] for p in pts]
        ax.set_title(f"{model}, n={min(p[6] for p in pts)}/point; not converged: "
                     + ",".join(str(s) for s in stalled), fontsize=8)
        ax.set_xlabel("fieldDefiance")
        ax.set_ylabel("convergence (mean of converged runs, 95% CI)", fontsize=8)
        ax.set_yscale("log")       # fieldDefiance 0's stall would flatten the rest
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"Graph 1 in both units (activation {', '.join(act)})", fontsize=10)
    fig.tight_layout()
    return _save(fig, path)


def polygon(points: Sequence[tuple[int, int]]) -> list[tuple[float, float]]:
    """The closed polygon through the points in angle order about their
    centroid (duplicates dropped): the outline a reader draws through the
    holders of shape.txt."""
    pts = sorted(set(points))
    if len(pts) < 2:
        return [(float(x), float(y)) for x, y in pts]
    mx = sum(x for x, _ in pts) / len(pts)
    my = sum(y for _, y in pts) / len(pts)
    pts.sort(key=lambda p: (math.atan2(p[1] - my, p[0] - mx), p))
    return [(float(x), float(y)) for x, y in pts + [pts[0]]]


def _pairs(text) -> list[tuple[int, int]]:
    return [tuple(int(v) for v in p.split(":")) for p in str(text or "").split()]  # type: ignore


def _true_cells(r: dict) -> list[tuple[int, int]]:
    """The object's cells at the start of the run a sweep row describes."""
    from sim_backend.scenario import validate
    from sim_backend.sweep import row_keys
    from sim_backend.world import World
    sc = validate({k: _num(r[k]) for k in row_keys(r) if r.get(k) not in (None, "")})
    return World(sc, int(_num(r["seed"]))).object_cells


def _draw_holders(ax, obj: str, n: int, r: dict | None) -> None:
    """One panel: the object, its holders' rounded positions, their polygon."""
    ax.set_xticks([])
    ax.set_yticks([])
    if r is None:
        ax.axis("off")
        return
    true = _true_cells(r)
    holders = _pairs(r.get("touches"))
    ax.scatter([c[0] for c in true], [c[1] for c in true], marker="s", s=60, c="#f2d06b")
    if holders:
        poly = polygon(holders)
        ax.plot([p[0] for p in poly], [p[1] for p in poly], "-", c="#c0392b", lw=1)
        ax.scatter([h[0] for h in holders], [h[1] for h in holders], s=18, c="#c0392b")
    pts = list(true) + holders
    ax.set_xlim(min(p[0] for p in pts) - 2, max(p[0] for p in pts) + 2)
    ax.set_ylim(min(p[1] for p in pts) - 2, max(p[1] for p in pts) + 2)
    ax.set_aspect("equal")
    ax.set_title(f"{obj}: {n} holders (seed {r['seed']}), IoU "
                 f"{float(_num(r['shape_iou'])):.2f}", fontsize=6)


def plot_shapes_thesis_way(rows: Sequence[dict], objs: Sequence[str], title: str,
                           path: Path) -> Path | None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shapes = [r for r in rows if r["experiment"] == "shapes"]
    objs = [o for o in objs if any(r["object"] == o for r in shapes)]
    if not objs:
        return None
    ns = sorted({int(math.ceil(float(_num(r["objectWeight"])) / float(_num(r["rPower"])) - 1e-9))
                 for r in shapes})
    panels = [[(obj, n, _example(rows, obj, n)) for n in ns] for obj in objs]
    fig, axes = plt.subplots(len(objs), len(ns), figsize=(2.2 * len(ns), 2.4 * len(objs)),
                             squeeze=False)
    for row_axes, line in zip(axes, panels):
        for ax, (obj, n, r) in zip(row_axes, line):
            _draw_holders(ax, obj, n, r)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    return _save(fig, path)


def plots(rows: Sequence[dict], out: Path) -> list[Path]:
    """Graph 1 in both units and Figures 22-24 the thesis's way."""
    paths = []
    p = plot_graph1_units(rows, out / "graph1_units.png")
    if p:
        paths.append(p)
    for name, objs in SHAPE_FIGURES.items():
        p = plot_shapes_thesis_way(rows, objs, f"Figure {name[3:5]} the thesis's way: holders' "
                                   f"rounded positions and the polygon through them "
                                   f"({', '.join(objs)})", out / f"{name}_thesis.png")
        if p:
            paths.append(p)
    return paths
