"""Watching a run: the per-tick observer seam, `run --trace` and `run --animate`.
Runs in-process through bridge.cli.main; no timing."""

from __future__ import annotations

import contextlib
import csv
import io
import json
import sys
import shutil
from pathlib import Path

from PIL import Image

from bridge import cli
from sim_backend import registry
from sim_backend import animate, observe, scenario
from sim_backend.engine import Engine, InprocLink
from sim_backend.trace import Trace, columns

THESIS_COLUMNS = ["tick", "n_search", "n_field", "n_grasp", "n_hold", "n_carry", "n_halt",
                  "power", "shape_iou", "polygon_iou", "touches", "msgs_up", "msgs_down",
                  "bad_frames", "holders", "home_d2",
                  "estimate_iou", "recognised", "p"]   # `touchswarm run` adds perception's


def run_cli(*argv: str) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = cli.main(list(argv))
        except SystemExit as exc:
            rc = exc.code
    return rc, out.getvalue(), err.getvalue()


def read_csv(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    with path.open() as f:
        rows = list(csv.DictReader(f))
    return list(rows[0].keys()) if rows else [], rows


def check_trace(names: list[str], rows: list[dict], summary: dict, states: tuple) -> None:
    """One row per tick, robots per state add up, the last row is the summary."""
    assert [int(r["tick"]) for r in rows] == list(range(1, summary["ticks"] + 1))
    for r in rows:
        assert sum(int(r[f"n_{s}"]) for s in states) == summary["robots"], r
    last = rows[-1]
    for world in ("power", "shape_iou", "polygon_iou"):   # only where the behaviour declares it
        assert (world in names) == (world in summary)
        if world in names:
            assert float(last[world]) == summary[world]
    assert int(last["touches"]) == len(summary["touches"])


def test_thesis_trace_has_one_row_per_tick_and_ends_at_the_summary(tmp_path):
    rc, out, err = run_cli("run", "--out", str(tmp_path / "o"), "--trace",
                           str(tmp_path / "t.csv"))
    assert rc == 0, err
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    names, rows = read_csv(tmp_path / "t.csv")
    assert names == THESIS_COLUMNS
    check_trace(names, rows, summary, registry.load("thesis").spec.STATES)
    # the run: touches arrive, then the holders carry the object home
    assert int(rows[-1]["holders"]) == len(summary["touches"])
    assert int(rows[-1]["n_carry"]) > 0 and int(rows[0]["n_search"]) == summary["robots"]
    assert sum(int(r["msgs_up"]) for r in rows) >= len(summary["touches"])
    assert f"({summary['ticks']} rows)" in out


def test_aggregate_trace_as_parquet_carries_its_reporters(tmp_path):
    import pyarrow.parquet as pq
    rc, _, err = run_cli("run", "--behaviour", "aggregate", "--out", str(tmp_path / "o"),
                         "--trace", str(tmp_path / "t.parquet"))
    assert rc in (0, 1), err
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    table = pq.read_table(tmp_path / "t.parquet")
    spec = registry.load("aggregate").spec
    assert table.column_names == [n for n, _ in columns(registry.load("aggregate"))]
    rows = [{k: str(v) for k, v in r.items()} for r in table.to_pylist()]
    check_trace(table.column_names, rows, summary, spec.STATES)
    for name, _ in spec.REPORTERS:
        assert int(rows[-1][name]) == summary[name], name


def test_trace_over_the_can_link(tmp_path):
    rc, _, err = run_cli("run", "--link", "can", "--robots", "8", "--set", "maxTicks=80",
                         "--out", str(tmp_path / "o"), "--trace", str(tmp_path / "t.csv"))
    assert rc in (0, 1), err
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    names, rows = read_csv(tmp_path / "t.csv")
    check_trace(names, rows, summary, registry.load("thesis").spec.STATES)
    # HELLO from every robot in the first tick, answered by one ACK each
    assert int(rows[0]["msgs_up"]) == 8 and int(rows[0]["msgs_down"]) == 8
    assert all(r["bad_frames"] == "0" for r in rows)


def test_no_snapshot_is_built_without_an_observer(monkeypatch):
    sc = scenario.load("default").replace(agents=6, maxTicks=40)
    plain = Engine(sc, 3).run().summary()

    def boom(engine):
        raise AssertionError("a snapshot was built with nobody observing")
    monkeypatch.setattr(observe, "snapshot", boom)
    assert Engine(sc, 3).run().summary() == plain
    monkeypatch.undo()
    # and observing does not change the run
    e = Engine(sc, 3)
    seen: list[int] = []
    e.observe(lambda s: seen.append(s.tick))
    assert e.run().summary() == plain and seen == list(range(1, 41))


def test_gif_has_the_expected_frames_and_size(tmp_path):
    gif = tmp_path / "run.gif"
    rc, out, err = run_cli("run", "--robots", "6", "--set", "maxTicks=35", "--animate", str(gif),
                           "--frame-every", "10")
    assert rc in (0, 1), err
    with Image.open(gif) as im:
        assert im.format == "GIF"
        assert im.size == (round(animate.FIGSIZE[0] * animate.DPI),
                           round(animate.FIGSIZE[1] * animate.DPI))
        assert im.n_frames == 5 == animate.frame_count(35, 10)   # ticks 0, 10, 20, 30, 35
        im.seek(im.n_frames - 1)
        im.load()
    assert "(5 frames, one every 10 ticks)" in out


def test_automatic_stride_keeps_at_most_max_frames():
    sc = scenario.load("default").replace(agents=6, maxTicks=300)
    e = Engine(sc, 2)
    anim = animate.Animation(e, observe.Trails(e))
    e.run()
    anim.finish()
    assert e.tick == 300 and anim.every == 4            # 1, then 2 at tick 120, 4 at 240
    assert len(anim.frames) == animate.frame_count(300, 4) <= animate.MAX_FRAMES
    assert [f.tick for f in anim.frames[:3]] == [0, 4, 8]


def test_mp4_without_ffmpeg_is_refused_before_the_run(tmp_path, monkeypatch):
    monkeypatch.setattr(shutil, "which", lambda name: None)   # animate imports it when used
    rc, out, err = run_cli("run", "--animate", str(tmp_path / "run.mp4"))
    assert rc == 2 and out == ""
    assert "needs ffmpeg on PATH" in err and len(err.strip().splitlines()) == 1
    assert list(tmp_path.iterdir()) == []


def test_parquet_without_pyarrow_is_refused_before_the_run(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)      # import pyarrow now fails
    rc, out, err = run_cli("run", "--trace", str(tmp_path / "t.parquet"))
    assert rc == 2 and out == ""
    assert ".parquet needs pyarrow" in err and len(err.strip().splitlines()) == 1
    assert "touchswarm[parquet]" in err
    assert list(tmp_path.iterdir()) == []


class NoisyLink(InprocLink):
    """An in-process link whose host side refuses two frames in its 5th
    exchange and one in its 9th, counted the way CanLink counts them."""

    def __init__(self, nodes: list[int]) -> None:
        super().__init__(nodes)
        self.exchanges = 0
        self.refused = {"wrong dlc": 0, "unknown id": 0}

    def poll(self, timeout: float):
        self.exchanges += 1
        if self.exchanges == 5:
            self.refused["wrong dlc"] += 2
        if self.exchanges == 9:
            self.refused["unknown id"] += 1
        return super().poll(timeout)

    def bad_frames(self) -> dict[str, int]:
        return dict(self.refused)


def test_bad_frames_are_counted_in_the_tick_they_arrive():
    sc = scenario.load("default").replace(agents=5, maxTicks=12)
    e = Engine(sc, 1, link=NoisyLink(list(range(1, 6))))
    trace = Trace(e)
    e.run()
    bad = [row[trace.names.index("bad_frames")] for row in trace.rows]
    assert bad == [0, 0, 0, 0, 2, 0, 0, 0, 1, 0, 0, 0]
