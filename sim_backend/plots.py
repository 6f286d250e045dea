"""PNG plots of sweep rows: the thesis's Graphs 1-4 and Figures 22-24.

Rows are the dicts of sim_backend.sweep (or the same read back from its CSV:
values may be strings). Convergence is in ticks; a run that never converged
within maxTicks is counted at maxTicks (censored) and the count is shown.
"""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path
from typing import Sequence

GRAPHS = {
    "graph1": ("fieldDefiance", "Graph 1: field defiance vs convergence"),
    "graph2": ("sigRadius", "Graph 2: signal radius vs convergence"),
    "graph3": ("rPower", "Graph 3: robot power vs convergence"),
    "graph4": ("required", "Graph 4: robots required (population 20) vs convergence"),
}
SHAPE_FIGURES = {
    "fig22_bar": ("bar",),
    "fig23_L_plus": ("L", "cross"),
    "fig24_X": ("X",),
}


def _num(v):
    if v is None or v == "":
        return None
    if isinstance(v, (int, float)):
        return v
    try:
        f = float(v)
    except ValueError:
        return v
    return int(f) if f.is_integer() else f


def _conv(r) -> tuple[float, bool]:
    c = _num(r["converged_tick"])
    if c is None:
        return float(_num(r["maxTicks"])), False
    return float(c), True


def _stats(vals: list[float]) -> tuple[float, float, float]:
    n = len(vals)
    m = sum(vals) / n
    sd = math.sqrt(sum((v - m) ** 2 for v in vals) / (n - 1)) if n > 1 else 0.0
    s = sorted(vals)
    med = s[n // 2] if n % 2 else (s[n // 2 - 1] + s[n // 2]) / 2
    return m, sd / math.sqrt(n) if n else 0.0, med


def convergence_table(rows: Sequence[dict], experiment: str, factor: str) -> dict:
    """{model: [(x, mean, sem, median, n, censored)]} of convergence ticks."""
    groups: dict[tuple[str, float], list] = defaultdict(list)
    for r in rows:
        if r["experiment"] != experiment:
            continue
        groups[(r["movementModel"], _num(r[factor]))].append(_conv(r))
    out: dict[str, list] = defaultdict(list)
    for (model, x), vals in sorted(groups.items(), key=lambda kv: (kv[0][0], kv[0][1])):
        ticks = [v for v, _ in vals]
        m, sem, med = _stats(ticks)
        out[model].append((x, m, sem, med, len(vals), sum(1 for _, ok in vals if not ok)))
    return dict(out)


def shape_table(rows: Sequence[dict], experiment: str = "shapes") -> dict:
    """{object: [(N, mean IoU, sem, mean touches, n)]}."""
    groups: dict[tuple[str, int], list] = defaultdict(list)
    for r in rows:
        if r["experiment"] == experiment:
            n = int(math.ceil(float(_num(r["objectWeight"])) / float(_num(r["rPower"])) - 1e-9))
            groups[(r["object"], n)].append((float(_num(r["shape_iou"])),
                                             int(_num(r["n_touches"]))))
    out: dict[str, list] = defaultdict(list)
    for (obj, n), vals in sorted(groups.items()):
        m, sem, _ = _stats([v for v, _ in vals])
        out[obj].append((n, m, sem, sum(t for _, t in vals) / len(vals), len(vals)))
    return dict(out)


def plot_convergence(rows: Sequence[dict], experiment: str, factor: str, title: str,
                     path: Path, source: str | None = None) -> Path | None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = convergence_table(rows, source or experiment, factor)
    if not table:
        return None
    models = [m for m in ("firefly", "ant") if m in table] + \
        [m for m in table if m not in ("firefly", "ant")]
    fig, axes = plt.subplots(1, len(models), figsize=(4.6 * len(models), 3.6), squeeze=False)
    ymax = max(m + s for pts in table.values() for _, m, s, *_ in pts) * 1.1
    for ax, (letter, model) in zip(axes[0], zip("abcd", models)):
        pts = table[model]
        xs = [p[0] for p in pts]
        ax.errorbar(xs, [p[1] for p in pts], yerr=[1.96 * p[2] for p in pts], marker="o",
                    capsize=3, label="mean (95% CI)")
        ax.plot(xs, [p[3] for p in pts], "s--", alpha=0.6, label="median")
        cens = sum(p[5] for p in pts)
        n = min(p[4] for p in pts)
        ax.set_title(f"({letter}) {model}, n={n}/point" + (f", {cens} censored" if cens else ""),
                     fontsize=9)
        ax.set_xlabel(factor)
        ax.set_ylabel("convergence (ticks)")
        ax.set_ylim(0, ymax)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


def _example(rows, obj, n):
    """The run of median IoU among those at (obj, N)."""
    cand = [r for r in rows if r["experiment"] == "shapes" and r["object"] == obj
            and int(math.ceil(float(_num(r["objectWeight"])) / float(_num(r["rPower"])) - 1e-9))
            == n]
    if not cand:
        return None
    cand.sort(key=lambda r: (float(_num(r["shape_iou"])), int(_num(r["seed"]))))
    return cand[len(cand) // 2]


def plot_shapes(rows: Sequence[dict], objs: Sequence[str], title: str, path: Path) -> Path | None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from firmware_logic import perception
    from sim_backend.scenario import validate
    from sim_backend.sweep import SCENARIO_KEYS
    from sim_backend.world import World

    table = shape_table(rows)
    objs = [o for o in objs if o in table]
    if not objs:
        return None
    ns = sorted({p[0] for o in objs for p in table[o]})
    fig, axes = plt.subplots(len(objs), len(ns) + 1, figsize=(2.1 * (len(ns) + 1), 2.3 * len(objs)),
                             squeeze=False)
    for row_axes, obj in zip(axes, objs):
        for ax, n in zip(row_axes, ns):
            ax.set_xticks([])
            ax.set_yticks([])
            r = _example(rows, obj, n)
            if r is None:
                ax.axis("off")
                continue
            # breeds (a tuple, "()" in a CSV) are not numbers: a shapes point has none
            sc = validate({k: _num(r[k]) for k in SCENARIO_KEYS
                           if r.get(k) not in (None, "", (), "()")})
            true = World(sc, int(_num(r["seed"]))).object_cells
            segs = [tuple(int(v) for v in p.split(":")) for p in str(r["segments"]).split()]
            outline = perception.outline_cells(segs)
            xs = [c[0] for c in true]
            ys = [c[1] for c in true]
            ax.scatter(xs, ys, marker="s", s=60, c="#f2d06b", label="object")
            if outline:
                ax.scatter([c[0] for c in outline], [c[1] for c in outline], marker="s", s=18,
                           c="#4a7bd0", alpha=0.5, label="perceived")
            if segs:
                ax.scatter([c[0] for c in segs], [c[1] for c in segs], marker="x", s=25,
                           c="k", label="touched")
            ax.set_xlim(min(xs) - 2, max(xs) + 2)
            ax.set_ylim(min(ys) - 2, max(ys) + 2)
            ax.set_aspect("equal")
            ax.set_title(f"{obj}: {n} robots, IoU {float(_num(r['shape_iou'])):.2f}", fontsize=7)
        ax = row_axes[-1]
        pts = table[obj]
        ax.errorbar([p[0] for p in pts], [p[1] for p in pts], yerr=[1.96 * p[2] for p in pts],
                    marker="o", capsize=3)
        ax.set_ylim(0, 1)
        ax.set_xlabel("touching robots", fontsize=7)
        ax.set_ylabel("mean IoU", fontsize=7)
        ax.tick_params(labelsize=6)
        ax.grid(alpha=0.3)
        ax.set_title(f"{obj}: n={min(p[4] for p in pts)}/point", fontsize=7)
    fig.suptitle(title, fontsize=9)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80)
    plt.close(fig)
    return path


def thesis_plots(rows: Sequence[dict], out: Path) -> list[Path]:
    """Every thesis graph and figure the rows hold data for."""
    paths = []
    for name, (factor, title) in GRAPHS.items():
        source = "graph3" if name == "graph4" else name
        p = plot_convergence(rows, name, factor, title, out / f"{name}.png", source=source)
        if p:
            paths.append(p)
    for name, objs in SHAPE_FIGURES.items():
        num = name[3:5]
        p = plot_shapes(rows, objs, f"Figure {num}: extracted shape vs touching robots "
                        f"({', '.join(objs)})", out / f"{name}.png")
        if p:
            paths.append(p)
    return paths


def grid_plots(rows: Sequence[dict], factors: Sequence[str], out: Path) -> list[Path]:
    """Convergence against each swept numeric factor, per movement model."""
    paths = []
    for f in factors:
        vals = {_num(r[f]) for r in rows}
        if len(vals) < 2 or not all(isinstance(v, (int, float)) for v in vals):
            continue
        p = plot_convergence(rows, rows[0]["experiment"], f, f"{f} vs convergence",
                             out / f"convergence_vs_{f}.png")
        if p:
            paths.append(p)
    return paths
