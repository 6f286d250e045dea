"""The host's shape estimate drawn where the run is shown:
world.png's shape panel and the animation draw the estimate (filled green
cells) beside the hull and the truth, with its verdict. Small runs in the
reference engine."""

from __future__ import annotations

import numpy as np
from PIL import Image

from perception.tracker import attach
from sim_backend import animate, observe, render, scenario
from sim_backend.engine import Engine

SC = scenario.load("default").replace(maxTicks=90)


def _run(watch: bool, anim: bool = False):
    e = Engine(SC, 2)
    p = attach(e) if watch else None
    trails = observe.Trails(e)
    a = animate.Animation(e, trails, every=45) if anim else None
    r = e.run()
    return e, p, trails, a, r


def test_world_png_draws_the_estimate_beside_hull_and_truth(tmp_path):
    _, p, trails, _, r = _run(True)
    est, name, prob = p.estimate_view()
    assert est and name == "bar"
    fig = render.figure(r, trails)
    panel = fig.axes[1]                          # the shape panel (then the colour bar)
    green = [q for q in panel.patches
             if tuple(np.round(q.get_facecolor()[:3], 3)) == render.ESTIMATE_RGB]
    assert len(green) == len(est)
    corners = {(round(q.get_x() + .5), round(q.get_y() + .5)) for q in green}
    assert corners == est
    assert "estimate (green" in panel.get_title() and "bar, p 1.00" in panel.get_title()
    out = render.render(r, tmp_path / "world.png", trails)
    assert Image.open(out).size[0] > 0
    # a run nothing watched has no estimate to draw, and the panel says nothing of one
    _, _, trails2, _, r2 = _run(False)
    assert "estimate" not in render.figure(r2, trails2).axes[1].get_title()


def test_the_animation_draws_the_estimate_where_the_object_is(tmp_path):
    e, p, _, anim, _ = _run(True, anim=True)
    last = anim.frames[-1]
    est, name, prob = p.estimate_view()
    dx, dy = render.displacement(e.world)
    assert set(last.estimate) == {(x + dx, y + dy) for x, y in est}
    assert last.verdict == f"{name}, p {prob:.2f}"
    assert "estimate: bar" in anim.title(last)
    assert anim.frames[0].estimate == ()          # before the first touch
    gif = tmp_path / "run.gif"
    anim.write(gif)
    _, _, _, plain, _ = _run(False, anim=True)
    gif2 = tmp_path / "plain.gif"
    plain.write(gif2)
    with Image.open(gif) as a, Image.open(gif2) as b:
        a.seek(a.n_frames - 1)
        b.seek(b.n_frames - 1)
        diff = np.asarray(a.convert("RGB"), dtype=int) - np.asarray(b.convert("RGB"), dtype=int)
    assert np.abs(diff).sum() > 0                # the estimate is in the picture


def test_the_shapes_figure_plots_the_estimate_beside_the_hull(tmp_path, monkeypatch):
    """Figures 22-24 (the studies' `shapes` kind): the IoU panel has the
    host's estimate (sweep.csv's estimate_iou) beside the hull."""
    import touchswarm
    from sim_backend import plots
    rows = touchswarm.sweep({"objectWeight": [4.0]}, seeds=2, engine="reference",
                            progress=False, object="L", maxTicks=300).to_dict("records")
    fig = {"experiment": "grid", "levels": ["L"], "category": "object", "title": "t"}
    table = plots.estimate_table(rows, fig)
    assert [p[0] for p in table["L"]] == [4] and table["L"][0][3] == 2
    saved = []
    monkeypatch.setattr(plots, "_save", lambda f, path: saved.append(f) or path)
    assert plots.shapes_plot(rows, fig, tmp_path / "fig.png") is not None
    iou_panel = saved[0].axes[-1]
    labels = [t.get_text() for t in iou_panel.get_legend().get_texts()]
    assert labels == ["hull", "host's estimate"]


def test_the_sweep_plots_have_an_estimate_panel_when_rows_carry_it():
    """The sweep plots draw the host's estimate IoU beside the behaviour's
    own panels; rows without it get no such panel."""
    from sim_backend import plots
    rows = [{"behaviour": "thesis", "seed": s, "maxTicks": 100, "shape_iou": 0.5,
             "estimate_iou": 0.9, "converged_tick": 50, "delivered": True} for s in (1, 2)]
    names = [p[0] for p in plots.panels(rows)]
    assert "estimate_iou" in names and "shape_iou" in names
    assert plots._panel_values(rows, ("estimate_iou", "", "value")) == [0.9, 0.9]
    for r in rows:
        r["estimate_iou"] = None
    assert "estimate_iou" not in [p[0] for p in plots.panels(rows)]
