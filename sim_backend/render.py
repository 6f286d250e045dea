"""PNG of a finished run: the world beside the perceived and the true shape."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.patches import Circle, Patch  # noqa: E402

from firmware_logic import fixedpoint as fx  # noqa: E402
from sim_backend.engine import RunResult  # noqa: E402
from sim_backend.world import BLUE, YELLOW  # noqa: E402


def render(result: RunResult, path: Path) -> Path:
    w = result.world
    n, half = w.n, w.w
    field = np.array(w.field, dtype=float).reshape(n, n)
    obj = np.array(w.obj).reshape(n, n)
    ext = (-half - 0.5, half + 0.5, -half - 0.5, half + 0.5)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(12, 6))
    ax1.imshow(field, origin="lower", extent=ext, cmap="Reds", alpha=0.6)
    rgba = np.zeros((n, n, 4))
    rgba[obj == YELLOW] = (1.0, 0.85, 0.0, 1.0)
    rgba[obj == BLUE] = (0.1, 0.3, 0.9, 1.0)
    ax1.imshow(rgba, origin="lower", extent=ext)
    ax1.add_patch(Circle((w.sc.homeX, w.sc.homeY), 2, color="c", alpha=0.5))
    # the robots the coordinator counts: carriers for the thesis; any
    # behaviour's reporters otherwise (the seam asks only for `touches`)
    carriers = {t.node for t in result.coordinator.touches}
    leader = result.coordinator.leader
    for r, x, y in zip(result.robots, w.xs, w.ys):
        colour = "red" if r.node == leader else ("green" if r.node in carriers else "dimgray")
        ax1.plot(x / fx.ONE, y / fx.ONE, "o", color=colour, ms=6)
    ax1.set_title(f"world at tick {result.ticks} (seed {result.seed}, "
                  f"{w.sc.agents} {w.sc.movementModel} robots)")
    ax1.legend(handles=[Patch(color=(1, .85, 0), label="object"),
                        Patch(color=(.1, .3, .9), label="held segment"),
                        Patch(color="red", label="leader"), Patch(color="green", label="carrier"),
                        Patch(color="dimgray", label="other robot"),
                        Patch(color="c", label="home")], loc="upper right", fontsize=7)
    truth = set(result.true_cells())
    seen = result.perceived_cells()
    pts = truth | seen
    xs = [p[0] for p in pts]
    ys = [p[1] for p in pts]
    for (x, y) in truth:
        ax2.add_patch(plt.Rectangle((x - .5, y - .5), 1, 1, color=(1, .85, 0), alpha=.6))
    for (x, y) in seen:
        ax2.add_patch(plt.Rectangle((x - .5, y - .5), 1, 1, fill=False, ec="blue", lw=2))
    for sx, sy in result.coordinator.segments_now():   # where the touched cells are now
        ax2.plot(sx, sy, "x", color="navy")
    ax2.set_xlim(min(xs) - 1.5, max(xs) + 1.5)
    ax2.set_ylim(min(ys) - 1.5, max(ys) + 1.5)
    ax2.set_aspect("equal")
    ax2.set_title(f"perceived (blue outline, x = touched) vs true (yellow): "
                  f"IoU {result.shape_iou():.2f}")
    for ax in (ax1, ax2):
        ax.set_xlabel("x (patches)")
        ax.set_ylabel("y (patches)")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80, metadata={"Software": None})
    plt.close(fig)
    return path
