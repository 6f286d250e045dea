"""PNG of a finished run: the world beside the perceived and the true shape
(a behaviour declaring spec.SHAPE) or beside its measures and reporters.

The drawing helpers here (field, object, trails, touch numbers) are shared
with the animation (sim_backend/animate.py), so a frame of the GIF and
world.png read the same way.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Sequence, cast

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Circle, Patch  # noqa: E402

from firmware_logic import fixedpoint as fx  # noqa: E402
from sim_backend import registry  # noqa: E402
from sim_backend.engine import RunResult  # noqa: E402
from sim_backend.world import BLUE, OBSTACLE, YELLOW  # noqa: E402

FIELD_CMAP = "Reds"
OBJECT_RGB = (1.0, 0.85, 0.0)
ESTIMATE_RGB = (0.1, 0.6, 0.2)     # the host's shape estimate (perception)
HELD_RGB = (0.1, 0.3, 0.9)
OBSTACLE_RGB = (0.35, 0.35, 0.35)
HOME_RADIUS = 2


def state_colours(names: tuple[str, ...]) -> list[tuple]:
    """One colour per state code, the same in every figure."""
    cmap = plt.get_cmap("tab10")
    return [cmap(i % 10) for i in range(len(names))]


def extent(w: Any) -> tuple[float, float, float, float]:
    return (-w.w - 0.5, w.w + 0.5, -w.w - 0.5, w.w + 0.5)


def object_rgba(obj: np.ndarray) -> np.ndarray:
    """The objects' patches (yellow), held segments (blue) and obstacles
    (grey), transparent elsewhere."""
    rgba = np.zeros(obj.shape + (4,))
    rgba[obj == OBSTACLE] = (*OBSTACLE_RGB, 1.0)
    rgba[obj == YELLOW] = (*OBJECT_RGB, 1.0)
    rgba[obj == BLUE] = (*HELD_RGB, 1.0)
    return rgba


def draw_base(ax: Any, w: Any, field: np.ndarray, vmax: float) -> tuple[Any, Any]:
    """The field (with a colour bar) and the home; returns the two images to update."""
    ext = extent(w)
    img = ax.imshow(field, origin="lower", extent=ext, cmap=FIELD_CMAP, vmin=0,
                    vmax=max(vmax, 1), alpha=0.7)
    ax.figure.colorbar(img, ax=ax, fraction=0.046, pad=0.02,
                       label="potential field (sum of lit beacons)")
    objimg = ax.imshow(np.zeros(field.shape + (4,)), origin="lower", extent=ext)
    ax.add_patch(Circle((w.sc.homeX, w.sc.homeY), HOME_RADIUS, color="c", alpha=0.4))
    ax.set_xlim(ext[0], ext[1])
    ax.set_ylim(ext[2], ext[3])
    ax.set_aspect("equal")
    ax.set_xlabel("x (patches)")
    ax.set_ylabel("y (patches)")
    return img, objimg


def trail_segments(xs: np.ndarray, ys: np.ndarray, states: np.ndarray,
                   colours: list[tuple]) -> tuple[Sequence[np.ndarray], list[tuple]]:
    """Line segments of every robot's path, tick to tick, each coloured by
    the state the robot was in at the segment's end. xs, ys, states: (ticks, robots)."""
    # one (segments, 2, 2) array, not a list of 2x2 arrays: LineCollection
    # takes either (a sequence of segments), and the array is one allocation
    if len(xs) < 2:
        return cast(Sequence[np.ndarray], np.zeros((0, 2, 2))), []
    a = np.stack([xs[:-1], ys[:-1]], axis=-1)       # (ticks-1, robots, 2)
    b = np.stack([xs[1:], ys[1:]], axis=-1)
    segs = np.stack([a, b], axis=2).reshape(-1, 2, 2)
    return cast(Sequence[np.ndarray], segs), [colours[s] for s in states[1:].reshape(-1)]


def touch_labels(ax: Any, touches: tuple, xs: tuple, ys: tuple) -> list[Any]:
    """Number the accepted touches in arrival order beside the robot that
    made each (it holds the object, so the number moves with the object)."""
    out = []
    seen: set[int] = set()
    for node, *_ in touches:
        if node in seen:
            continue
        seen.add(node)
        out.append(ax.annotate(str(len(seen)), (xs[node - 1], ys[node - 1]), xytext=(3, 3),
                               textcoords="offset points", fontsize=7, weight="bold",
                               color="black"))
    return out


def state_legend(names: tuple[str, ...], colours: list[tuple]) -> list[Any]:
    return [Line2D([], [], color=c, lw=2, label=f"state {n}") for n, c in zip(names, colours)]


def render(result: RunResult, path: Path, trails: Any = None) -> Path:
    """world.png (figure() drawn and saved)."""
    fig = figure(result, trails)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=80, metadata={"Software": None})
    plt.close(fig)
    return path


def figure(result: RunResult, trails: Any = None) -> Any:
    """world.png's figure: the world at the end, beside the perceived and the
    true shape when the behaviour declares a shape measure (spec.SHAPE), else
    beside its measures and reporters with their titles (sim_backend/words.py).
    With `trails` (observe.Trails) also start positions, every robot's path
    coloured by state, and the object's path home."""
    from sim_backend import words
    w = result.world
    snap_field = np.array(w.field, dtype=float).reshape(w.n, w.n)
    behaviour = registry.load(result.scenario.behaviour)
    said = words.of(behaviour)
    names = tuple(behaviour.spec.STATES)
    colours = state_colours(names)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 6), width_ratios=(1.15, 1))
    _, objimg = draw_base(ax1, w, snap_field, snap_field.max())
    objimg.set_data(object_rgba(np.array(w.obj).reshape(w.n, w.n)))
    handles: list[Patch | Line2D] = [Patch(color="c", label="home")]
    if w.object_cells:
        handles[:0] = [Patch(color=OBJECT_RGB, label="object at the end"),
                       Patch(color=HELD_RGB, label="held segment")]
    if w.decoy_cells:
        # decoys are objects too (yellow): outlined and named, so a reader
        # tells them from the target
        for (x, y) in w.decoy_cells:
            ax1.add_patch(plt.Rectangle((x - .5, y - .5), 1, 1, fill=False, ec="darkred",
                                        lw=1.2, hatch="xx", zorder=2))
        handles[0] = Patch(color=OBJECT_RGB, label="target at the end")
        handles.append(Patch(fill=False, ec="darkred", hatch="xx", label="decoy (not the target)"))
    if w.obstacle_cells:
        handles.append(Patch(color=OBSTACLE_RGB, label="obstacle"))
    if trails is not None:
        xs, ys, states = trails.arrays()
        segs, cols = trail_segments(xs, ys, states, colours)
        ax1.add_collection(LineCollection(segs, colors=cols, linewidths=0.4, alpha=0.5))
        ax1.plot(xs[0], ys[0], "o", mfc="none", mec="black", ms=5)
        handles.append(Line2D([], [], marker="o", mfc="none", mec="black", ls="",
                              label="start position"))
        if trails.centre:
            centre = np.array(trails.centre)
            ax1.plot(centre[:, 0], centre[:, 1], "--", color="darkcyan", lw=2)
            handles.append(Line2D([], [], ls="--", color="darkcyan", lw=2,
                                  label="object's path (its centre)"))
        handles += state_legend(names, colours)
    xs_now = tuple(x / fx.ONE for x in w.xs)
    ys_now = tuple(y / fx.ONE for y in w.ys)
    final_states = [r.state for r in result.robots]
    ax1.scatter(xs_now, ys_now, s=30, c=[colours[s] for s in final_states],
                edgecolors="black", linewidths=0.5, zorder=3)
    touches = tuple((t.node, t.tick) for t in result.coordinator.touches)
    touch_labels(ax1, touches, xs_now, ys_now)
    handles.append(Line2D([], [], marker="$1$", color="black", ls="",
                          label="touch order (by the robot that made it)"))
    lit = sum(w.beacon_on)
    ax1.set_title(f"world at tick {result.ticks} (seed {result.seed}, {w.sc.agents} robots, "
                  f"behaviour {said.name})\nfield as the world holds it then: "
                  f"{lit} beacon(s) lit where their robots lit them", fontsize=9)
    ax1.legend(handles=handles, loc="best", fontsize=6, framealpha=0.8)
    if said.shape is not None and result.true_cells():
        _shape_panel(ax2, result, said.label(said.shape))
    else:
        _measures_panel(ax2, result, behaviour, said)
    fig.tight_layout()
    return fig


def _measures_panel(ax: Any, result: RunResult, behaviour: Any, said: Any) -> None:
    """The behaviour's measures and reporters at the end, each with its title."""
    from sim_backend import words
    values = words.summary_values(behaviour, result.summary(), result.coordinator)
    ax.axis("off")
    ax.set_title(f"{said.name}: measures and reporters at tick {result.ticks}", fontsize=9)
    rows = words.shown_values(said, values)
    for i, r in enumerate(rows):
        ax.text(0.0, 1.0 - (i + 0.5) / max(len(rows) + 1, 12), f"{r['title']}: "
                f"{words.named_text(r['name'], r['value'])}", transform=ax.transAxes, fontsize=8,
                va="center", wrap=True)


def estimate_of(instruments: Any) -> tuple[set, str | None, float] | None:
    """The host's shape estimate from a watching measure that has one (a
    perception Perceiver: estimate_cells(), its summary's verdict), in the
    object's own frame; None when nothing watched the run."""
    for inst in instruments or ():
        view = getattr(inst, "estimate_view", None)
        if view is not None:
            return view()
    return None


def displacement(world: Any) -> tuple[int, int]:
    """How far the carried object has moved from where it stood at the start."""
    if not world.start_cells:
        return 0, 0
    return (world.object_cells[0][0] - world.start_cells[0][0],
            world.object_cells[0][1] - world.start_cells[0][1])


def draw_estimate(ax: Any, cells: set, shift: tuple[int, int] = (0, 0)) -> Any:
    """The estimate as filled green cells (hatched, so the truth shows through)."""
    patch = None
    for (x, y) in cells:
        patch = ax.add_patch(plt.Rectangle((x + shift[0] - .5, y + shift[1] - .5), 1, 1,
                                           color=ESTIMATE_RGB, alpha=.45, hatch="//", lw=0))
    return patch


def verdict_text(recognised: str | None, p: float) -> str:
    return f"{recognised}, p {p:.2f}" if recognised else f"undecided, p {p:.2f}"


def _shape_panel(ax2: Any, result: RunResult, label: str) -> None:
    """The perceived shape (the touched cells' hull) and the host's estimate
    (filled cells, with its verdict) against the true one, all in the
    object's own frame (where it stood at the start), as the measures are."""
    from firmware_logic import perception
    truth = set(result.world.start_cells)
    c = result.coordinator
    mx, my = getattr(c, "moved_x", 0), getattr(c, "moved_y", 0)
    segs = [(x - mx, y - my) for x, y in c.segments_now()]
    seen = perception.outline_cells(segs)
    est = estimate_of(result.instruments)
    pts = truth | seen | (est[0] if est else set())
    for (x, y) in truth:
        ax2.add_patch(plt.Rectangle((x - .5, y - .5), 1, 1, color=OBJECT_RGB, alpha=.6))
    if est:
        draw_estimate(ax2, est[0])
    for (x, y) in seen:
        ax2.add_patch(plt.Rectangle((x - .5, y - .5), 1, 1, fill=False, ec="blue", lw=2))
    for i, (sx, sy) in enumerate(segs, 1):
        ax2.plot(sx, sy, "x", color="navy")
        ax2.annotate(str(i), (sx, sy), xytext=(3, 3), textcoords="offset points", fontsize=8)
    ax2.set_xlim(min(p[0] for p in pts) - 1.5, max(p[0] for p in pts) + 1.5)
    ax2.set_ylim(min(p[1] for p in pts) - 1.5, max(p[1] for p in pts) + 1.5)
    ax2.set_aspect("equal")
    ax2.set_xlabel("x (patches, the object's frame at the start)")
    # on the right: on the left it met the world panel's colour-bar label
    ax2.yaxis.set_label_position("right")
    ax2.yaxis.tick_right()
    ax2.set_ylabel("y (patches)")
    title = (f"hull (blue outline, x = touched, numbered in order) vs true "
             f"(yellow): {label} {result.shape_iou():.2f}")
    if est:
        inter, union = perception.iou_counts(est[0], truth)
        title += (f"\nestimate (green, hatched): IoU {inter / union if union else 0:.2f}, "
                  f"{verdict_text(est[1], est[2])}")
    ax2.set_title(title, fontsize=9)
