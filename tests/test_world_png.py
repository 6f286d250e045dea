"""world.png names what it draws: a decoy is outlined and in the
legend apart from the target, and the shape panel's y label sits on its right,
clear of the world panel's colour bar."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

from sim_backend import engine, render, scenario  # noqa: E402


def test_world_png_labels_the_decoy_and_keeps_the_labels_apart() -> None:
    sc = scenario.load("decoy")
    result = engine.Engine(sc.replace(maxTicks=60), seed=1).run()
    fig = render.figure(result)
    ax1, *rest = fig.axes
    labels = [t.get_text() for t in ax1.get_legend().get_texts()]
    assert "decoy (not the target)" in labels and "target at the end" in labels
    hatched = [p for p in ax1.patches if p.get_hatch() == "xx"]
    assert len(hatched) == len(result.world.decoy_cells) > 0
    shape = next(a for a in rest if a.get_ylabel() == "y (patches)")
    assert shape.yaxis.get_label_position() == "right"
    matplotlib.pyplot.close(fig)
    plain = render.figure(engine.Engine(scenario.load("default").replace(maxTicks=30), 1).run())
    labels = [t.get_text() for t in plain.axes[0].get_legend().get_texts()]
    assert "decoy (not the target)" not in labels and "object at the end" in labels
    matplotlib.pyplot.close(plain)
