"""PNG plots of sweep rows: a --grid sweep's figures (grid_plots: the
behaviour's measures against each swept key) and the figure kinds a
behaviour's studies draw (sim_backend/studies.py FIGURES: factor, units,
shapes, touchmap, rates, levels; the thesis's Graphs 1-4 and Figures 22-24
are its studies.py's figures of these kinds).

Rows are the dicts of sim_backend.sweep (or the same read back from its CSV:
values may be strings). Every column a study's figure draws is named by the
study. Ticks: a run whose tick measure never came within maxTicks is counted
at maxTicks (censored) and the count is shown.
"""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path
from typing import Sequence

def _num(v):
    if v is None or v == "":
        return None
    if isinstance(v, (int, float)):
        return v
    if v in ("True", "False"):        # a boolean key (wrap) as the CSV writes it
        return v == "True"
    try:
        f = float(v)
    except ValueError:
        return v
    return int(f) if f.is_integer() else f


def _stats(vals: list[float]) -> tuple[float, float, float]:
    n = len(vals)
    m = sum(vals) / n
    sd = math.sqrt(sum((v - m) ** 2 for v in vals) / (n - 1)) if n > 1 else 0.0
    s = sorted(vals)
    med = s[n // 2] if n % 2 else (s[n // 2 - 1] + s[n // 2]) / 2
    return m, sd / math.sqrt(n) if n else 0.0, med


def _factor_levels(rows: Sequence[dict], factor: str) -> list:
    """The factor's distinct values in the rows, in first-seen (grid) order."""
    return list(dict.fromkeys(_num(r[factor]) for r in rows))


def is_numeric(rows: Sequence[dict], factor: str) -> bool:
    return all(isinstance(v, (int, float)) and not isinstance(v, bool)
               for v in _factor_levels(rows, factor))


def _groups(rows: Sequence[dict], others: Sequence[str]) -> dict[tuple, list[dict]]:
    """Rows by the values of the other factors (one curve or box set each)."""
    out: dict[tuple, list[dict]] = {}
    for r in rows:
        out.setdefault(tuple(_num(r[f]) for f in others), []).append(r)
    return out


def _group_label(others: Sequence[str], key: tuple) -> str:
    return ", ".join(f"{f}={v}" for f, v in zip(others, key)) or "all runs"


def _mean_ci(vals: list[float]) -> tuple[float, float]:
    """Mean and the half-width of its normal 95% interval (0 for n < 2)."""
    if not vals:
        return math.nan, 0.0
    m, sem, _ = _stats(vals)
    return m, 1.96 * sem


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float, float]:
    """A proportion k/n and its Wilson score 95% interval (lo, hi), always
    inside [0, 1] (a normal interval runs past 1 for a rate near 1)."""
    if n == 0:
        return math.nan, math.nan, math.nan
    p = k / n
    d = 1 + z * z / n
    centre = (p + z * z / (2 * n)) / d
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / d
    return p, max(0.0, centre - half), min(1.0, centre + half)


def _rate_ci(vals: list[float]) -> tuple[float, float, float]:
    """A rate's proportion and how far its Wilson interval reaches below and above."""
    p, lo, hi = wilson(int(round(sum(vals))), len(vals))
    return p, p - lo, hi - p


def axis_label(factor: str, rows: Sequence[dict] = ()) -> str:
    """A factor's axis label with its unit: a world key's from
    scenario.UNITS, the sweep's derived columns', else the meaning the rows'
    behaviours give the parameter in spec.PARAMS."""
    from sim_backend import params, scenario
    unit = scenario.UNITS.get(factor) or DERIVED_UNITS.get(factor)
    if unit is None:
        from sim_backend.scenario import DEFAULT_BEHAVIOUR
        for b in dict.fromkeys(r.get("behaviour") or DEFAULT_BEHAVIOUR for r in rows):
            unit = next((p.meaning for p in params.declared(b) if p.name == factor), None)
            if unit:
                break
    if not unit:
        return factor
    import textwrap
    return textwrap.shorten(f"{factor} ({unit}", 60, placeholder="...") + ")"


# columns the sweep adds to its rows (sim_backend/sweep.py), with their units
DERIVED_UNITS = {"required": "robots needed to hold the weight"}


def _delivered(r) -> float:
    return 1.0 if str(r["delivered"]) in ("True", "true", "1") else 0.0


def panels(rows: Sequence[dict]) -> list[tuple[str, str, str]]:
    """(measure, label, kind) of each panel of a grid figure: the measures the
    rows' behaviours declare (their spec.PLOTS, else every spec.MEASURES
    measure with numbers or true/false in the rows; sim_backend/words.py)."""
    from sim_backend import words
    from sim_backend.scenario import DEFAULT_BEHAVIOUR
    behaviours = list(dict.fromkeys(r.get("behaviour") or DEFAULT_BEHAVIOUR for r in rows))
    names = {k for r in rows for k in r}
    cols = {k: [_num(r.get(k)) for r in rows] for k in names}
    return words.plot_panels(behaviours, cols)


def _declares(rows: Sequence[dict], measure: str) -> list[dict]:
    """The rows whose behaviour declares `measure` (a column another
    behaviour's rows leave empty is no data, not a run that never got there)."""
    from sim_backend import words
    from sim_backend.scenario import DEFAULT_BEHAVIOUR
    if measure in dict(words.INSTRUMENT_PLOTS):
        return [r for r in rows if _num(r.get(measure)) is not None]
    cache: dict[str, bool] = {}
    out = []
    for r in rows:
        b = r.get("behaviour") or DEFAULT_BEHAVIOUR
        if b not in cache:
            cache[b] = measure in dict(words.of(b).measures)
        if cache[b]:
            out.append(r)
    return out


def _tick(r, measure: str) -> tuple[float, bool]:
    """A tick measure's value, or maxTicks (censored) when it never happened."""
    c = _num(r.get(measure))
    if c is None:
        return float(_num(r["maxTicks"])), False
    return float(c), True


def _panel_values(rs: list[dict], panel: tuple[str, str, str]) -> list[float]:
    measure, _, kind = panel
    rs = _declares(rs, measure)
    if kind == "tick":
        return [c for c, ok in (_tick(r, measure) for r in rs) if ok]
    vals = [_num(r.get(measure)) for r in rs]
    return [float(v) for v in vals if v is not None and v != ""]


def _censored(rs: list[dict], panel: tuple[str, str, str]) -> list[float]:
    """The censoring tick (maxTicks) of every run whose tick measure never came."""
    measure, _, kind = panel
    if kind != "tick":
        return []
    return [c for c, ok in (_tick(r, measure) for r in _declares(rs, measure)) if not ok]


# the y axis says the statistic; the panel's title says the measure
FACTOR_LABELS = {"tick": "tick (runs that got there: mean, 95% CI)",
                 "rate": "fraction of runs (Wilson 95% CI)",
                 "value": "mean, 95% CI"}
CATEGORY_LABELS = {"tick": "tick (runs that got there; box: quartiles)",
                   "rate": "fraction of runs (Wilson 95% CI)",
                   "value": "box: quartiles"}


def _title(rows: Sequence[dict], factor: str, pans: list) -> str:
    from sim_backend.scenario import DEFAULT_BEHAVIOUR
    names = ", ".join(dict.fromkeys(r.get("behaviour") or DEFAULT_BEHAVIOUR for r in rows))
    return f"{factor}: {len(pans)} measure{'s' if len(pans) != 1 else ''} of {names}"


def _panel_title(label: str) -> str:
    import textwrap
    return textwrap.fill(label, 38)


def factor_figure(rows: Sequence[dict], factor: str, others: Sequence[str]):
    """The behaviour's measures against a numeric factor, one panel each
    (panels()), one curve per combination of the other factors' levels
    (never pooled), n per point in each curve's label; runs whose tick
    measure never came are drawn as hollow markers at their censoring tick
    (maxTicks). Returns the Figure; curves carry gid "curve", censored
    markers gid "censored"; each panel's title is its measure's label."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pans = panels(rows)
    groups = _groups(rows, others)
    fig, axes = plt.subplots(1, len(pans), figsize=(4.6 * len(pans), 3.8), squeeze=False)
    xs_all = sorted(set(_num(r[factor]) for r in rows))
    span = (xs_all[-1] - xs_all[0]) or 1.0
    for gi, (key, rs) in enumerate(groups.items()):
        by_x: dict = defaultdict(list)
        for r in rs:
            by_x[_num(r[factor])].append(r)
        xs = sorted(by_x)
        n = min(len(by_x[x]) for x in xs)
        label = f"{_group_label(others, key)} (n={n}/point)"
        # a small sideways shift per curve keeps overlapping points apart
        dx = span * 0.012 * (gi - (len(groups) - 1) / 2)
        for ax, panel in zip(axes[0], pans):
            if panel[2] == "rate":
                # a rate's interval is the Wilson score interval: inside [0, 1]
                rates = [_rate_ci(_panel_values(by_x[x], panel)) for x in xs]
                ys = [p for p, _, _ in rates]
                yerr: list[float] | list[list[float]]     # one per point, or [lows, highs]
                yerr = [[lo for _, lo, _ in rates], [hi for _, _, hi in rates]]
            else:
                stats = [_mean_ci(_panel_values(by_x[x], panel)) for x in xs]
                ys, yerr = [m for m, _ in stats], [ci for _, ci in stats]
            cont = ax.errorbar([x + dx for x in xs], ys, yerr=yerr, marker="o", capsize=3,
                               label=label)
            cont.lines[0].set_gid("curve")
            color = cont.lines[0].get_color()
            cx = [x + dx for x in xs for _ in _censored(by_x[x], panel)]
            cy = [c for x in xs for c in _censored(by_x[x], panel)]
            if cx:
                sc = ax.scatter(cx, cy, facecolors="none", edgecolors=color, s=36,
                                label=f"{_group_label(others, key)}: {len(cx)} censored "
                                      "at maxTicks")
                sc.set_gid("censored")
    for ax, (measure, label, kind) in zip(axes[0], pans):
        ax.set_xticks(xs_all)
        ax.set_xlabel(axis_label(factor, rows), fontsize=9)
        ax.set_title(_panel_title(label), fontsize=9)
        ax.set_ylabel(FACTOR_LABELS[kind], fontsize=8)
        if kind == "rate":
            ax.set_ylim(-0.05, 1.05)
        elif kind == "tick":
            ax.set_ylim(bottom=0)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.suptitle(f"{_title(rows, factor, pans)} "
                 f"({len(rows)} runs, {len(groups)} curve{'s' if len(groups) > 1 else ''})",
                 fontsize=10)
    fig.tight_layout()
    return fig


def category_figure(rows: Sequence[dict], factor: str, others: Sequence[str]):
    """A categorical factor (object, behaviour, a choice parameter...): one panel
    per measure (panels()), boxes of ticks and values and bars of rates per
    level, one coloured set per combination of the other factors' levels, n
    under each level; censored runs as hollow markers at maxTicks. Returns
    the Figure; boxes carry gid "box", bars gid "bar", censored markers gid
    "censored"; each panel's title is its measure's label."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    pans = panels(rows)
    levels = _factor_levels(rows, factor)
    groups = _groups(rows, others)
    width = 0.8 / len(groups)
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    fig, axes = plt.subplots(1, len(pans), figsize=(max(4.6, 1.4 * len(levels) * len(groups))
                                                    * len(pans) / 2, 3.8), squeeze=False)
    ns: dict = defaultdict(list)
    cens_all = 0
    for gi, (key, rs) in enumerate(groups.items()):
        color = colors[gi % len(colors)]
        label = _group_label(others, key)
        for li, level in enumerate(levels):
            at = [r for r in rs if _num(r[factor]) == level]
            if not at:
                continue
            ns[level].append(len(at))
            x = li - 0.4 + width * (gi + 0.5)
            for ax, panel in zip(axes[0], pans):
                vals = _panel_values(at, panel)
                if panel[2] == "rate":
                    if vals:
                        p, lo, hi = _rate_ci(vals)     # Wilson: inside [0, 1]
                        bars = ax.bar([x], [p], width * 0.9, color=color,
                                      yerr=[[lo], [hi]], capsize=3, ecolor="black",
                                      label=label if li == 0 else None)
                        for b in bars:
                            b.set_gid("bar")
                    continue
                if vals:
                    # outliers as small dots: hollow circles mean censored runs here
                    bp = ax.boxplot([vals], positions=[x], widths=width * 0.8,
                                    patch_artist=True, manage_ticks=False,
                                    flierprops={"marker": ".", "markersize": 4,
                                                "markerfacecolor": color,
                                                "markeredgecolor": color})
                    for b in bp["boxes"]:
                        b.set_facecolor(color)
                        b.set_alpha(0.6)
                        b.set_gid("box")
                        b.set_label(label if li == 0 else None)
                cens = _censored(at, panel)
                cens_all += len(cens)
                if cens:
                    sc = ax.scatter([x] * len(cens), cens, facecolors="none",
                                    edgecolors=color, s=36)
                    sc.set_gid("censored")
    ticks = [f"{lv}\n(n={'/'.join(str(n) for n in ns[lv])})" for lv in levels]
    for ax, (measure, label, kind) in zip(axes[0], pans):
        ax.set_xticks(range(len(levels)), ticks, fontsize=8)
        ax.set_xlabel(axis_label(factor, rows), fontsize=9)
        ax.set_title(_panel_title(label), fontsize=9)
        ax.set_ylabel(CATEGORY_LABELS[kind], fontsize=8)
        if kind == "rate":
            ax.set_ylim(-0.05, 1.05)
        ax.grid(alpha=0.3, axis="y")
        if len(groups) > 1 and kind == "rate":
            ax.legend(fontsize=8)
    fig.suptitle(f"{_title(rows, factor, pans)} per level ({len(rows)} runs"
                 + (f", {cens_all} censored at maxTicks: hollow markers" if cens_all else "")
                 + ")", fontsize=10)
    fig.tight_layout()
    return fig


def _save(fig, path: Path, dpi: int = 80) -> Path:
    import matplotlib.pyplot as plt
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=dpi)
    plt.close(fig)
    return path


def grid_plots(rows: Sequence[dict], factors: Sequence[str], out: Path) -> list[Path]:
    """One figure per swept factor with at least two levels, `by_<factor>.png`:
    a numeric factor as curves (factor_figure), a categorical one as boxes
    and bars (category_figure); the other swept factors split the curves."""
    paths = []
    swept = [f for f in factors if len(_factor_levels(rows, f)) > 1]
    for f in swept:
        others = [o for o in swept if o != f]
        fig = (factor_figure if is_numeric(rows, f) else category_figure)(rows, f, others)
        paths.append(_save(fig, out / f"by_{f}.png"))
    return paths


# -- the figure kinds of a behaviour's studies (sim_backend/studies.py FIGURES):
# fn(rows, figure, path) -> path or None when the rows hold no data for it;
# every column comes from the figure's keys

def _of(rows: Sequence[dict], fig: dict) -> list[dict]:
    """The rows of the figure's experiment (every row when it names none)."""
    exp = fig.get("experiment")
    return [r for r in rows if exp is None or r["experiment"] == exp]


def _series(rows: Sequence[dict], fig: dict) -> list:
    """The series column's values in first-seen (point) order; one series
    (None) when the figure has none."""
    col = fig.get("series")
    return list(dict.fromkeys(_num(r[col]) for r in rows)) if col else [None]


def _meaning(rows: Sequence[dict], col: str) -> str:
    """What the rows' behaviour says a measure column is (spec.MEASURES), or
    the column's name."""
    from sim_backend import words
    from sim_backend.scenario import DEFAULT_BEHAVIOUR
    b = next((r.get("behaviour") for r in rows if r.get("behaviour")), DEFAULT_BEHAVIOUR)
    try:
        return dict(words.of(b).measures).get(col, col)
    except Exception:          # noqa: BLE001 - a label only; the rows were made by it
        return col


def _in(r: dict, fig: dict, value) -> bool:
    col = fig.get("series")
    return col is None or _num(r[col]) == value


def _by_series_and_x(rows: Sequence[dict], fig: dict) -> dict:
    """{series value: {x: [rows]}} of the figure's experiment, series in
    first-seen order (one series, None, when the figure has none)."""
    rs = _of(rows, fig)
    out: dict = {}
    for value in _series(rs, fig):
        by_x: dict = defaultdict(list)
        for r in rs:
            if _in(r, fig, value):
                by_x[_num(r[fig["x"]])].append(r)
        out[value] = by_x
    return out


def factor_table(rows: Sequence[dict], fig: dict) -> dict:
    """{series value: [(x, mean, sem, median, n, censored)]} of the tick
    column y against x (a run whose y never came counts at maxTicks)."""
    out: dict = {}
    for value, by_x in _by_series_and_x(rows, fig).items():
        pts = []
        for x in sorted(by_x):
            vals = [_tick(r, fig["y"]) for r in by_x[x]]
            m, sem, med = _stats([v for v, _ in vals])
            pts.append((x, m, sem, med, len(vals), sum(1 for _, ok in vals if not ok)))
        out[value] = pts
    return out


def factor_plot(rows: Sequence[dict], fig: dict, path: Path) -> Path | None:
    """Kind factor: the tick column y against x, one panel per series value:
    mean (95% CI), median, and each censored run at maxTicks."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = factor_table(rows, fig)
    if not any(table.values()):
        return None
    x, y = fig["x"], fig["y"]
    rs = _of(rows, fig)
    f, axes = plt.subplots(1, len(table), figsize=(4.6 * len(table), 3.6), squeeze=False)
    ymax = max(m + s for pts in table.values() for _, m, s, *_ in pts) * 1.1
    for ax, (letter, value) in zip(axes[0], zip("abcdefgh", table)):
        pts = table[value]
        xs = [p[0] for p in pts]
        ax.errorbar(xs, [p[1] for p in pts], yerr=[1.96 * p[2] for p in pts], marker="o",
                    capsize=3, label="mean (95% CI)")
        ax.plot(xs, [p[3] for p in pts], "s--", alpha=0.6, label="median")
        censored = [r for r in rs if _in(r, fig, value) and not _tick(r, y)[1]]
        if censored:
            # every censored run drawn at its censoring tick, not only counted
            sc = ax.scatter([_num(r[x]) for r in censored], [_tick(r, y)[0] for r in censored],
                            facecolors="none", edgecolors="C3", s=30,
                            label="censored at maxTicks")
            sc.set_gid("censored")
            ymax = max(ymax, max(_tick(r, y)[0] for r in censored) * 1.05)
        cens = sum(p[5] for p in pts)
        n = min(p[4] for p in pts)
        name = "all runs" if value is None else value
        ax.set_title(f"({letter}) {name}, n={n}/point" + (f", {cens} censored" if cens else ""),
                     fontsize=9)
        ax.set_xlabel(axis_label(x, rows))
        ax.set_ylabel(fig.get("ylabel", f"{y} (ticks)"))
        ax.set_ylim(0, ymax)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    import textwrap
    f.suptitle(fig.get("title") or textwrap.fill(f"{y}: {_meaning(rs, y)}, against {x}",
                                                 50 * len(table)), fontsize=10)
    f.tight_layout()
    return _save(f, path)


def units_table(rows: Sequence[dict], fig: dict) -> dict:
    """{series value: [(x, (mean, sem) per y column, got there, runs)]} over
    the runs whose first y column came."""
    cols = [c for c, _ in fig["y"]]
    out: dict = {}
    for value, by_x in _by_series_and_x(rows, fig).items():
        pts = []
        for x in sorted(by_x):
            done = [r for r in by_x[x] if _num(r[cols[0]]) is not None]
            stats = [(_stats([float(_num(r[c])) for r in done])[:2] if done else (math.nan, 0.0))
                     for c in cols]
            pts.append((x, stats, len(done), len(by_x[x])))
        out[value] = pts
    return out


def units_plot(rows: Sequence[dict], fig: dict, path: Path) -> Path | None:
    """Kind units: several tick columns y ((column, label), ...) against x on
    a log scale (a stalled level would flatten the rest), one panel per
    series value, over the runs that got there; the panel's title counts
    those that did not."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = units_table(rows, fig)
    if not any(table.values()):
        return None
    act = sorted({str(r.get("activation", "sync")) for r in _of(rows, fig)})
    f, axes = plt.subplots(1, len(table), figsize=(4.8 * len(table), 3.6), squeeze=False)
    for ax, value in zip(axes[0], table):
        pts = table[value]
        xs = [p[0] for p in pts]
        for i, (_, label) in enumerate(fig["y"]):
            ax.errorbar(xs, [p[1][i][0] for p in pts], yerr=[1.96 * p[1][i][1] for p in pts],
                        marker="os^v"[i % 4], capsize=3, label=label)
        stalled = [p[3] - p[2] for p in pts]
        name = "all runs" if value is None else value
        ax.set_title(f"{name}, n={min(p[3] for p in pts)}/point; not reached: "
                     + ",".join(str(s) for s in stalled), fontsize=8)
        ax.set_xlabel(axis_label(fig["x"], rows))
        ax.set_ylabel(fig.get("ylabel", f"{fig['y'][0][0]} (mean of the runs that got there, "
                                        "95% CI)"), fontsize=8)
        ax.set_yscale("log")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    f.suptitle(f"{fig.get('title', fig['x'])} (activation {', '.join(act)})", fontsize=10)
    f.tight_layout()
    return _save(f, path)


def _n(r) -> int:
    """The robots that must hold the run's object (sweep.csv's `required`)."""
    return int(_num(r["required"]))


def shape_table(rows: Sequence[dict], fig: dict, col: str = "") -> dict:
    """{category value: [(N, mean IoU, sem, mean touches, n)]}: N the robots
    required to hold it; the IoU column `col`, else the figure's y, else
    shape_iou."""
    cat = fig.get("category", "object")
    col = col or fig.get("y", "shape_iou")
    groups: dict[tuple, list] = defaultdict(list)
    for r in _of(rows, fig):
        groups[(r[cat], _n(r))].append((float(_num(r[col])), int(_num(r["n_touches"]))))
    out: dict[str, list] = defaultdict(list)
    for (obj, n), vals in sorted(groups.items()):
        m, sem, _ = _stats([v for v, _ in vals])
        out[obj].append((n, m, sem, sum(t for _, t in vals) / len(vals), len(vals)))
    return dict(out)


def estimate_table(rows: Sequence[dict], fig: dict) -> dict:
    """{category value: [(N, mean estimate IoU, sem, n)]} over the rows that
    carry the host's estimate (sweep.csv's estimate_iou)."""
    cat = fig.get("category", "object")
    groups: dict[tuple, list] = defaultdict(list)
    for r in _of(rows, fig):
        v = _num(r.get("estimate_iou"))
        if isinstance(v, (int, float)):
            groups[(r[cat], _n(r))].append(float(v))
    out: dict[str, list] = defaultdict(list)
    for (obj, n), vals in sorted(groups.items()):
        m, sem, _ = _stats(vals)
        out[obj].append((n, m, sem, len(vals)))
    return dict(out)


def _example(rows: Sequence[dict], fig: dict, obj, n):
    """The run of median IoU (the figure's y, else shape_iou) among those at
    (category value, N)."""
    cat = fig.get("category", "object")
    col = fig.get("y", "shape_iou")
    cand = [r for r in _of(rows, fig) if r[cat] == obj and _n(r) == n]
    if not cand:
        return None
    cand.sort(key=lambda r: (float(_num(r[col])), int(_num(r["seed"]))))
    return cand[len(cand) // 2]


def _true_cells(r: dict) -> list[tuple[int, int]]:
    """The object's cells at the start of the run a sweep row describes."""
    from sim_backend.scenario import validate
    from sim_backend.sweep import row_keys
    from sim_backend.world import World
    # breeds (a tuple, "()" in a CSV) are not numbers: such a point has none
    sc = validate({k: _num(r[k]) for k in row_keys(r) if r.get(k) not in (None, "", (), "()")})
    return World(sc, int(_num(r["seed"]))).object_cells


def shapes_plot(rows: Sequence[dict], fig: dict, path: Path) -> Path | None:
    """Kind shapes: per level of the category (rows) and required holders N
    (columns) the median-IoU run's perceived shape over the true cells, and
    a last panel of mean IoU against N."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from firmware_logic import perception

    table = shape_table(rows, fig)
    objs = [o for o in fig["levels"] if o in table]
    if not objs:
        return None
    ns = sorted({p[0] for o in objs for p in table[o]})
    f, axes = plt.subplots(len(objs), len(ns) + 1, figsize=(2.1 * (len(ns) + 1), 2.3 * len(objs)),
                           squeeze=False)
    for row_axes, obj in zip(axes, objs):
        for ax, n in zip(row_axes, ns):
            ax.set_xticks([])
            ax.set_yticks([])
            r = _example(rows, fig, obj, n)
            if r is None:
                ax.axis("off")
                continue
            true = _true_cells(r)
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
                    marker="o", capsize=3, label="hull")
        est = estimate_table(rows, fig).get(obj)
        if est:
            ax.errorbar([p[0] for p in est], [p[1] for p in est],
                        yerr=[1.96 * p[2] for p in est], marker="s", capsize=3, color="C2",
                        label="host's estimate")
            ax.legend(fontsize=6)
        _iou_axes(ax, obj, pts, "mean IoU")
    f.suptitle(fig.get("title", "extracted shape vs touching robots"), fontsize=9)
    f.tight_layout()
    return _save(f, path)


def _pairs(text) -> list[tuple[int, int]]:
    return [tuple(int(v) for v in p.split(":")) for p in str(text or "").split()]  # type: ignore


def _draw_touches(ax, obj: str, n: int, r: dict | None, col: str) -> None:
    """One panel: the object, the run's touches (holders' rounded positions),
    their polygon and the cells it encloses (perception/polygon.py)."""
    from perception.polygon import enclosed_cells, polygon
    ax.set_xticks([])
    ax.set_yticks([])
    if r is None:
        ax.axis("off")
        return
    true = _true_cells(r)
    holders = _pairs(r.get("touches"))
    ax.scatter([c[0] for c in true], [c[1] for c in true], marker="s", s=60, c="#f2d06b")
    inside = enclosed_cells(holders)
    if inside:
        ax.scatter([c[0] for c in inside], [c[1] for c in inside], marker="s", s=18,
                   c="#c0392b", alpha=0.35)
    if holders:
        poly = polygon(holders)
        ax.plot([p[0] for p in poly], [p[1] for p in poly], "-", c="#c0392b", lw=1)
        ax.scatter([h[0] for h in holders], [h[1] for h in holders], s=18, c="#c0392b")
    pts = list(true) + holders
    ax.set_xlim(min(p[0] for p in pts) - 2, max(p[0] for p in pts) + 2)
    ax.set_ylim(min(p[1] for p in pts) - 2, max(p[1] for p in pts) + 2)
    ax.set_aspect("equal")
    ax.set_title(f"{obj}: {n} holders (seed {r['seed']}), IoU "
                 f"{float(_num(r[col])):.2f}", fontsize=6)


def touchmap_plot(rows: Sequence[dict], fig: dict, path: Path) -> Path | None:
    """Kind touchmap: per level of the category and required holders N, the
    median run (of the figure's y, else shape_iou) drawn as its touches over
    the true cells, the polygon through them and the cells it encloses (a
    shape judged by eye, as a reader of the touches would), and a last panel
    of mean y (95% CI) against N, shape_iou beside it when y is another."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rs = _of(rows, fig)
    cat = fig.get("category", "object")
    col = fig.get("y", "shape_iou")
    objs = [o for o in fig["levels"] if any(r[cat] == o for r in rs)]
    if not objs:
        return None
    ns = sorted({_n(r) for r in rs})
    f, axes = plt.subplots(len(objs), len(ns) + 1, figsize=(2.2 * (len(ns) + 1), 2.4 * len(objs)),
                           squeeze=False)
    for row_axes, obj in zip(axes, objs):
        for ax, n in zip(row_axes, ns):
            _draw_touches(ax, obj, n, _example(rows, fig, obj, n), col)
        ax = row_axes[-1]
        if col != "shape_iou" and all(r.get("shape_iou") not in (None, "") for r in rs):
            pts = shape_table(rows, fig, "shape_iou").get(obj, [])
            ax.errorbar([p[0] for p in pts], [p[1] for p in pts],
                        yerr=[1.96 * p[2] for p in pts], marker="s", capsize=3, ls="--",
                        color="0.5", label="shape_iou")
        pts = shape_table(rows, fig, col).get(obj, [])
        ax.errorbar([p[0] for p in pts], [p[1] for p in pts], yerr=[1.96 * p[2] for p in pts],
                    marker="o", capsize=3, color="#c0392b", label=col)
        ax.legend(fontsize=5)
        _iou_axes(ax, obj, pts, "mean IoU (95% CI)")
    f.suptitle(fig.get("title", "touches and the polygon through them"), fontsize=9)
    f.tight_layout()
    return _save(f, path)


def rates_plot(rows: Sequence[dict], fig: dict, path: Path) -> Path | None:
    """Kind rates: delivery rate (of the feasible runs) and median delivery
    tick against the rate of each fault, one curve per experiment (named
    after the key it varies, sim_backend/robustness.fault_table); the
    reference experiment as a line; scale ((key, divisor), ...) puts a key
    that is not a rate on the same axis."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from sim_backend.robustness import fault_table
    ref = fig.get("reference")
    scale = dict(fig.get("scale", ()))
    table = fault_table(rows, ref)
    if not table:
        return None
    f, (a, b) = plt.subplots(1, 2, figsize=(11, 4.2))
    for exp, pts in table.items():
        if exp == ref:
            continue
        xs = [p[0] / scale.get(exp, 1) for p in pts]
        a.plot(xs, [p[2] / p[1] if p[1] else float("nan") for p in pts], "o-", label=exp)
        b.plot(xs, [p[3] if p[3] is not None else float("nan") for p in pts], "o-", label=exp)
    if ref in table:
        _, n, d, med = table[ref][0]
        a.axhline(d / n if n else 0, color="k", ls=":", label=f"{ref} ({d}/{n})")
    scaled = ", ".join(f"{k}: value / {v}" for k, v in scale.items())
    a.set_xlabel("fault rate" + (f" ({scaled})" if scaled else ""))
    a.set_ylabel("delivered / feasible runs")
    a.set_ylim(-0.02, 1.02)
    b.set_xlabel("fault rate")
    b.set_ylabel("median tick of delivery")
    a.legend(fontsize=7)
    f.suptitle(fig.get("title", "delivery against each fault's rate"))
    f.tight_layout()
    return _save(f, path, dpi=110)


def _iou_axes(ax, obj: str, pts: list, ylabel: str) -> None:
    """One object's panel of an IoU-against-touching-robots figure: axes,
    grid and a title with the fewest runs behind a point (p[4])."""
    ax.set_ylim(0, 1)
    ax.set_xlabel("touching robots", fontsize=7)
    ax.set_ylabel(ylabel, fontsize=7)
    ax.tick_params(labelsize=6)
    ax.grid(alpha=0.3)
    ax.set_title(f"{obj}: n={min((p[4] for p in pts), default=0)}/point", fontsize=7)


def levels_plot(rows: Sequence[dict], fig: dict, path: Path) -> Path | None:
    """Kind levels: boxes of the column y per experiment, in the order of
    levels ((experiment, label), ...), the mean as a line, and under each
    label the runs that got there of all."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    y = fig["y"]
    levels = [(exp, label) for exp, label in fig["levels"]
              if any(r["experiment"] == exp for r in rows)]
    if not levels:
        return None
    data, ticks, means = [], [], []
    for exp, label in levels:
        rs = [r for r in rows if r["experiment"] == exp]
        got = [float(_num(r[y])) for r in rs if _num(r[y]) is not None]
        data.append(got or [float("nan")])
        means.append(sum(got) / len(got) if got else float("nan"))
        ticks.append(f"{label}\n{len(got)}/{len(rs)}")
    xs = list(range(len(levels)))
    f, ax = plt.subplots(figsize=(6, 4))
    ax.boxplot(data, positions=xs, widths=0.5, showfliers=False)
    ax.plot(xs, means, "o-", label="mean")
    ax.set_xticks(xs, ticks)
    ax.set_xlabel(fig.get("xlabel", "experiment; runs that got there/runs"))
    ax.set_ylabel(fig.get("ylabel", y))
    ax.legend()
    f.suptitle(fig.get("title", f"{y} per level"))
    f.tight_layout()
    return _save(f, path, dpi=110)
