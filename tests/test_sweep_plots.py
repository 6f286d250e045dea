"""Sweep figures never pool: one curve per level of the other factor,
categorical factors as boxes and bars, delivery and IoU plotted, censored
runs drawn. Asserted on the figures' structure, not on pixels."""

import pytest

from bridge.cli import main
from sim_backend import plots


def fake_rows(grid: dict, seeds=range(1, 6), censor=lambda p, s: False) -> list[dict]:
    """Rows as sweep.csv holds them (strings), one per point and seed."""
    import itertools
    rows = []
    keys = list(grid)
    for combo in itertools.product(*grid.values()):
        p = dict(zip(keys, combo))
        for s in seeds:
            cens = censor(p, s)
            rows.append({"experiment": "grid", "movementModel": "firefly", "object": "bar",
                         "maxTicks": "3000", **{k: str(v) for k, v in p.items()},
                         "seed": str(s), "converged_tick": "" if cens else str(100 + 10 * s),
                         "delivered": str(not cens), "shape_iou": str(0.5 + 0.05 * s)})
    return rows


def curves(ax) -> list:
    return [ln for ln in ax.get_lines() if ln.get_gid() == "curve"]


def labels(ax) -> list[str]:
    """The curves' labels as the legend shows them."""
    from matplotlib.container import ErrorbarContainer
    return [c.get_label() for c in ax.containers if isinstance(c, ErrorbarContainer)]


def gid(ax, name: str) -> list:
    return [a for a in ax.get_children() if a.get_gid() == name]


def test_two_numeric_factors_give_one_curve_per_level_of_the_other():
    rows = fake_rows({"fieldDefiance": [1, 2], "sigRadius": [3, 5]})
    fig = plots.factor_figure(rows, "fieldDefiance", ["sigRadius"])
    conv, deliv, iou = fig.axes[:3]
    for ax in (conv, deliv, iou):
        assert len(curves(ax)) == 2
        assert labels(ax) == ["sigRadius=3 (n=5/point)", "sigRadius=5 (n=5/point)"]
        legend = [t.get_text() for t in ax.get_legend().get_texts()]
        assert legend[:2] == labels(ax)
    # each panel is one of the thesis's declared PLOTS, titled by its label
    assert [ax.get_title() for ax in (conv, deliv, iou)] == ["convergence tick",
                                                              "delivery rate", "shape IoU"]
    assert "fraction of runs" in deliv.get_ylabel() and "mean" in iou.get_ylabel()
    assert all(list(c.get_ydata()) == [1.0, 1.0] for c in curves(deliv))


def test_three_factors_split_by_every_combination_of_the_others():
    rows = fake_rows({"fieldDefiance": [1, 2], "sigRadius": [3, 5], "rPower": [1.0, 2.0]},
                     seeds=range(1, 4))
    fig = plots.factor_figure(rows, "fieldDefiance", ["sigRadius", "rPower"])
    assert len(curves(fig.axes[0])) == 4
    assert "sigRadius=5, rPower=2 (n=3/point)" in labels(fig.axes[0])


def test_censored_runs_are_drawn_at_their_censoring_tick():
    rows = fake_rows({"fieldDefiance": [1, 2]}, censor=lambda p, s: p["fieldDefiance"] == 2
                     and s <= 2)
    fig = plots.factor_figure(rows, "fieldDefiance", [])
    (marks,) = gid(fig.axes[0], "censored")
    offsets = marks.get_offsets()
    assert len(offsets) == 2 and all(y == 3000 for _, y in offsets)
    assert "2 censored" in marks.get_label()
    # the delivery rate shows them too: 3 of 5 delivered at fieldDefiance 2
    (deliv,) = curves(fig.axes[1])
    assert list(deliv.get_ydata()) == pytest.approx([1.0, 0.6])


def test_a_categorical_factor_gets_boxes_and_bars_per_level():
    rows = fake_rows({"object": ["bar", "L", "X"]}, censor=lambda p, s: p["object"] == "X"
                     and s == 1)
    fig = plots.category_figure(rows, "object", [])
    conv, deliv, iou = fig.axes[:3]
    assert len(gid(conv, "box")) == 3 and len(gid(iou, "box")) == 3
    assert len([p for p in deliv.patches if p.get_gid() == "bar"]) == 3
    assert [t.get_text() for t in conv.get_xticklabels()] == ["bar\n(n=5)", "L\n(n=5)",
                                                             "X\n(n=5)"]
    assert len(gid(conv, "censored")) == 1


def test_a_categorical_factor_with_a_second_factor_is_split_too():
    rows = fake_rows({"object": ["bar", "L"], "sigRadius": [3, 5]})
    fig = plots.category_figure(rows, "object", ["sigRadius"])
    assert len(gid(fig.axes[0], "box")) == 4
    labels = [t.get_text() for t in fig.axes[1].get_legend().get_texts()]
    assert labels == ["sigRadius=3", "sigRadius=5"]


def test_grid_plots_gives_a_figure_per_swept_factor(tmp_path):
    rows = fake_rows({"object": ["bar", "L", "X"], "fieldDefiance": [1, 2]})
    paths = plots.grid_plots(rows, ["object", "fieldDefiance"], tmp_path)
    assert [p.name for p in paths] == ["by_object.png", "by_fieldDefiance.png"]
    assert all(p.stat().st_size > 1000 for p in paths)


def test_cli_two_factor_sweep_and_categorical_sweep_plot(tmp_path):
    assert main(["sweep", "--grid", "fieldDefiance=1,2", "--grid", "sigRadius=3,5",
                 "--seeds", "2", "--set", "maxTicks=400", "--executor", "inline",
                 "--out", str(tmp_path / "a")]) == 0
    assert (tmp_path / "a" / "by_fieldDefiance.png").exists()
    assert (tmp_path / "a" / "by_sigRadius.png").exists()
    assert main(["sweep", "--grid", "object=bar,L,X", "--seeds", "2", "--set", "maxTicks=400",
                 "--executor", "inline", "--out", str(tmp_path / "b")]) == 0
    assert (tmp_path / "b" / "by_object.png").exists()


# -- rate intervals inside [0, 1], units on every axis -------------------


@pytest.mark.parametrize("k, n", [(0, 5), (5, 5), (3, 5), (1, 1), (50, 50), (1, 100)])
def test_wilson_interval_stays_inside_0_1_and_holds_the_rate(k, n):
    p, lo, hi = plots.wilson(k, n)
    assert 0.0 <= lo <= p <= hi <= 1.0 and p == k / n
    assert hi - lo > 0                       # never a zero-width interval, even at 0 or n


def test_wilson_matches_the_textbook_value():
    # 8 of 10: Wilson 95% interval 0.490..0.943 (Newcombe 1998, method 3)
    _, lo, hi = plots.wilson(8, 10)
    assert (round(lo, 3), round(hi, 3)) == (0.49, 0.943)


def test_a_rate_of_one_has_its_error_bar_inside_0_1_and_axes_have_units():
    rows = fake_rows({"sigRadius": [3, 5]})              # every run delivered: rate 1
    fig = plots.factor_figure(rows, "sigRadius", [])
    deliv = fig.axes[1]
    bars = [c for c in deliv.containers][0]
    segs = bars.lines[2][0].get_segments()               # the error bars' vertical lines
    assert all(0.0 <= y <= 1.0 for seg in segs for _, y in seg)
    assert min(y for seg in segs for _, y in seg) < 1.0  # an interval, not a point
    assert all(ax.get_xlabel() == "sigRadius (patches)" for ax in fig.axes)
    assert plots.axis_label("required") == "required (robots needed to hold the weight)"
    assert plots.axis_label("rPower", rows) == "rPower (power of one robot (weight units))"
    cat = plots.category_figure(fake_rows({"movementModel": ["firefly", "ant"]}),
                                "movementModel", [])
    assert all(ax.get_xlabel().startswith("movementModel (") for ax in cat.axes)
