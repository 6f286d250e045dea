"""`touchswarm run --animate FILE`: the run drawn over time as a GIF (or an
MP4 where ffmpeg is on PATH), from the engine's per-tick snapshots.

Each frame shows the field with a colour bar, the object and its held
segments, every robot's recent trail coloured by its state, the touches
numbered in order, the perceived shape (blue squares; a behaviour declaring
spec.SHAPE) and the object's path home; its title the tick and the
behaviour's reporters (sim_backend/words.py). Frames: the start, then every
`every` ticks, then the last tick.
With no `every`, the stride starts at 1 and doubles whenever more than
MAX_FRAMES frames are kept, so a long run stays a small file.
"""

from __future__ import annotations

import contextlib
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterator

import numpy as np

from sim_backend.observe import OutputFormatError, Snapshot, Trails, output_format

# matplotlib (and sim_backend.render, which draws with it) is imported by
# write() only: the command line checks --animate's suffix before a run
# (and reads MAX_FRAMES for its help), and a run without --animate never
# draws; shutil and subprocess (ffmpeg) likewise where they are used

SUFFIXES = (".gif", ".mp4")
MAX_FRAMES = 120
FPS = 10
TRAIL_TICKS = 30          # how far back a frame draws each robot's trail
FIGSIZE = (8.0, 7.6)      # inches; at DPI this gives 800 x 760 pixels: every label
DPI = 100                 # is 8 pt or more, legible at 100 %


def animation_format(path: Path) -> str:
    """"gif" or "mp4" from the suffix; mp4 needs ffmpeg on PATH."""
    import shutil
    fmt = output_format(path, SUFFIXES, "animation")
    if fmt == "mp4" and shutil.which("ffmpeg") is None:
        raise OutputFormatError(f"{path}: .mp4 needs ffmpeg on PATH, which is not there; "
                                "use .gif or install ffmpeg")
    return fmt


def frame_count(ticks: int, every: int) -> int:
    """Frames a run of `ticks` ticks gives at a stride of `every`."""
    return 1 + math.ceil(ticks / every)


@dataclass
class Frame:
    tick: int
    field: np.ndarray
    obj: np.ndarray
    touches: tuple
    perceived: tuple
    xs: tuple
    ys: tuple
    reporters: dict
    iou: float
    phase: str = ""            # the host's status() at this tick
    load: tuple | None = None  # the declared LOAD pair's values (spec.LOAD), weight units
    estimate: tuple = ()       # the host's shape estimate, where the object is now
    verdict: str = ""


def _frame(s: Snapshot, engine: Any, load: tuple | None, instruments: Any = ()) -> Frame:
    from sim_backend import render as rd
    c = engine.coordinator
    est: tuple = ()
    verdict = ""
    view = rd.estimate_of(instruments)
    if view is not None:
        dx, dy = rd.displacement(s._world)
        est = tuple((x + dx, y + dy) for x, y in view[0])
        verdict = rd.verdict_text(view[1], view[2]) if view[0] else ""
    return Frame(s.tick, s.field(), s.obj(), s.touches, tuple(s.perceived), s.xs, s.ys,
                 dict(s.reporters), s.iou, c.status(),
                 None if load is None else tuple(getattr(c, n) / 100 for n in load),
                 est, verdict)


class Animation:
    """Keeps frames from an engine's snapshots; `write` draws them."""

    def __init__(self, engine: Any, trails: Trails, every: int | None = None) -> None:
        self.world = engine.world
        self.names = tuple(engine.behaviour.spec.STATES)
        from sim_backend import words
        self.words = words.of(engine.behaviour)
        self.trails = trails
        self.fixed = every is not None
        self.every = every or 1
        self.engine = engine
        self.instruments = getattr(engine, "instruments", ())
        self.frames = [self._frame(engine.snapshot())]
        self.last: Snapshot | None = None
        engine.observe(self.add)

    def add(self, s: Snapshot) -> None:
        self.last = s
        if s.tick % self.every:
            return
        self.frames.append(self._frame(s))
        if not self.fixed and len(self.frames) > MAX_FRAMES:
            self.every *= 2
            self.frames = [f for f in self.frames if f.tick % self.every == 0]

    def finish(self) -> None:
        """Keep the last tick's frame. Only valid once the run has ended: a
        snapshot's grids are read from the world as it stands."""
        if self.last is not None and self.frames[-1].tick != self.last.tick:
            self.frames.append(self._frame(self.last))

    def _frame(self, s: Snapshot) -> Frame:
        return _frame(s, self.engine, self.words.load, self.instruments)

    def title(self, f: Frame) -> str:
        """A frame's title: its tick and the host's phase, then the declared
        load, the behaviour's reporters, the shape's score when the behaviour
        declares one (sim_backend/words.py)."""
        from sim_backend import words
        title = words.frame_title(self.words, f.tick, f.reporters, f.iou, f.phase, f.load)
        return f"{title}; estimate: {f.verdict}" if f.verdict else title

    def write(self, path: Path, progress: Callable[[int, int], None] | None = None) -> int:
        """Draw every kept frame and the last tick's to path; returns the
        count. progress(done, total) is called after each frame drawn."""
        from sim_backend import render as rd   # first: it selects the Agg backend
        import matplotlib.pyplot as plt
        from matplotlib.collections import LineCollection
        from matplotlib.lines import Line2D
        from matplotlib.patches import Patch
        self.finish()
        frames = self.frames
        fmt = animation_format(path)
        w = self.world
        colours = rd.state_colours(self.names)
        vmax = max(float(f.field.max()) for f in frames)
        fig, ax = plt.subplots(figsize=FIGSIZE, dpi=DPI)
        img, objimg = rd.draw_base(ax, w, frames[0].field, vmax)
        trail = LineCollection([], linewidths=1.0, alpha=0.8)
        ax.add_collection(trail)
        start_x, start_y = self.trails.xs[0], self.trails.ys[0]
        ax.plot(start_x, start_y, "o", mfc="none", mec="gray", ms=3)
        path_line, = ax.plot([], [], "--", color="darkcyan", lw=2)
        est = ax.scatter([], [], marker="s", s=22, color=rd.ESTIMATE_RGB, alpha=0.5,
                         linewidths=0, zorder=2)
        seen = ax.scatter([], [], marker="s", s=22, facecolors="none", edgecolors="blue",
                          linewidths=1.0, zorder=2)
        estimated = any(f.estimate for f in frames)
        dots = ax.scatter(start_x, start_y, s=18, edgecolors="black", linewidths=0.4, zorder=3)
        # sized for tight_layout by the first frame's words
        title = ax.set_title(self.title(frames[0]), fontsize=10)
        shape = self.words.shape is not None
        has_object = bool(self.trails.centre)
        handles: list[Patch | Line2D] = []
        if has_object:
            handles += [Patch(color=rd.OBJECT_RGB,
                              label="object or decoy" if w.decoy_cells else "object"),
                        Patch(color=rd.HELD_RGB, label="held segment")]
        if w.obstacle_cells:
            handles.append(Patch(color=rd.OBSTACLE_RGB, label="obstacle"))
        handles.append(Patch(color="c", alpha=0.4, label="home"))
        if shape:
            handles.append(Line2D([], [], marker="s", mfc="none", mec="blue", ls="",
                                  label="perceived shape"))
        if estimated:
            handles.append(Line2D([], [], marker="s", color=rd.ESTIMATE_RGB, alpha=0.5, ls="",
                                  label="host's estimate"))
        if has_object:
            handles.append(Line2D([], [], ls="--", color="darkcyan", label="object's path"))
        # below the arena, not over it
        legend = ax.legend(handles=[*handles, *rd.state_legend(self.names, colours)],
                           loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=4, fontsize=9,
                           framealpha=0.9)
        fig.tight_layout()
        # blitting: the axes' tick labels and the colour bar are drawn once;
        # each frame redraws only the artists inside the axes (a full redraw
        # lays out every text again and costs several times more)
        dynamic = [*ax.images, *ax.collections, *ax.lines, *ax.patches, legend,
                   title, *ax.spines.values()]
        for a in dynamic:
            a.set_animated(True)
        fig.canvas.draw()
        background = fig.canvas.copy_from_bbox(fig.bbox)
        labels: list[Any] = []
        with _sink(fmt, path, fig.canvas.get_width_height()) as sink:
            for done, f in enumerate(frames, 1):
                img.set_data(f.field)
                objimg.set_data(rd.object_rgba(f.obj))
                lo = max(0, f.tick - TRAIL_TICKS)
                xs, ys, states = (a[lo:] for a in self.trails.arrays(f.tick))
                segs, cols = rd.trail_segments(xs, ys, states, colours)
                trail.set_segments(segs)
                trail.set_color(cols)
                centre = np.array(self.trails.centre[:f.tick + 1]).reshape(-1, 2)
                path_line.set_data(centre[:, 0], centre[:, 1])
                if shape:
                    seen.set_offsets(np.array(f.perceived, dtype=float).reshape(-1, 2))
                est.set_offsets(np.array(f.estimate, dtype=float).reshape(-1, 2))
                dots.set_offsets(np.column_stack([f.xs, f.ys]))
                dots.set_facecolor([colours[s] for s in self.trails.states[f.tick]])
                for t in labels:
                    t.remove()
                labels = rd.touch_labels(ax, f.touches, f.xs, f.ys)
                title.set_text(self.title(f))
                fig.canvas.restore_region(background)
                for a in sorted(dynamic + labels, key=lambda a: a.get_zorder()):
                    ax.draw_artist(a)
                sink(np.asarray(fig.canvas.buffer_rgba())[..., :3])
                if progress is not None:
                    progress(done, len(frames))
        plt.close(fig)
        return len(frames)


@contextlib.contextmanager
def _sink(fmt: str, path: Path, size: tuple[int, int]) -> Iterator[Callable[[np.ndarray], object]]:
    """A function taking RGB frames (h, w, 3) that end up in path as a GIF
    (Pillow, one adaptive palette per frame) or an MP4 (ffmpeg, H.264)."""
    if fmt == "gif":
        from PIL import Image
        images: list[Any] = []
        yield lambda rgb: images.append(
            Image.fromarray(rgb).convert("P", palette=Image.Palette.ADAPTIVE))
        images[0].save(path, save_all=True, append_images=images[1:],
                       duration=1000 // FPS, loop=0)
        return
    import shutil
    import subprocess
    width, height = size
    proc = subprocess.Popen(
        [shutil.which("ffmpeg") or "ffmpeg", "-loglevel", "error", "-y", "-f", "rawvideo",
         "-pix_fmt", "rgb24", "-s", f"{width}x{height}", "-r", str(FPS), "-i", "-",
         "-pix_fmt", "yuv420p", "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", str(path)],
        stdin=subprocess.PIPE)
    stdin = proc.stdin
    assert stdin is not None             # opened with stdin=PIPE
    try:
        yield lambda rgb: stdin.write(np.ascontiguousarray(rgb).tobytes())
    finally:
        stdin.close()
        if proc.wait() != 0:
            raise OSError(f"ffmpeg failed writing {path} (exit status {proc.returncode})")
