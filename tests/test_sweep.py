"""Sweeps: grid expansion, tidy CSV, executors (processes, dask) give one CSV."""

from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

import pytest

from bridge.cli import main
from sim_backend import sweep
from sim_backend.errors import ScenarioError

GRID = {"fieldDefiance": [1, 4], "movementModel": ["firefly", "ant"]}
SEEDS = [1, 2, 3]
OVR = {"maxTicks": 3000}


def csv_text(tmp_path, name, **kw):
    rows = sweep.sweep(sweep.grid_points(GRID), SEEDS, overrides=OVR, chunk_size=5, **kw)
    return sweep.write_csv(rows, tmp_path / name).read_text(), rows


def but_engine(text):
    """A sweep.csv's text without its engine column (the one column that
    says which bit-identical engine ran the row)."""
    lines = [ln.split(",") for ln in text.splitlines()]
    at = lines[0].index("engine")
    return [ln[:at] + ln[at + 1:] for ln in lines]


def warm_step():
    """The grid's soa step loaded in this process: compiled first when the
    cache lacks it, or loaded once another process's compile of it ends
    (soa.compile_lock). Without it, `auto` found the step missing whenever
    another test process was compiling it (a clean clone's `make test -n 2`,
    a kernel edit), ran these sweeps in the reference engine while a
    background compile started, and the soa rows asserted below were
    reference rows: an order- and timing-dependent failure."""
    sweep.warm(sweep.point_scenarios(sweep.grid_points(GRID), overrides=OVR))


def test_grid_rows_and_reference_agree(tmp_path):
    warm_step()
    local, rows = csv_text(tmp_path, "a.csv")
    assert len(rows) == 12
    assert [(r["fieldDefiance"], r["movementModel"], r["seed"]) for r in rows[:4]] == [
        (1, "firefly", 1), (1, "firefly", 2), (1, "firefly", 3), (1, "ant", 1)]
    for key in ("sigRadius", "rPower", "object", "converged_tick", "shape_iou", "segments"):
        assert key in rows[0]
    ref, ref_rows = csv_text(tmp_path, "b.csv", engine="reference")
    assert but_engine(ref) == but_engine(local) and ref != local
    assert {r["engine"] for r in rows} == {"soa"}
    assert {r["engine"] for r in ref_rows} == {"reference"}
    with ThreadPoolExecutor(2) as ex:
        threaded, _ = csv_text(tmp_path, "c.csv", executor=ex)
    assert threaded == local


def test_dask_local_cluster_gives_the_same_csv(tmp_path):
    distributed = pytest.importorskip("distributed")
    local, _ = csv_text(tmp_path, "local.csv")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=2, processes=False,
                                  protocol="tcp", host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        with distributed.Client(cluster) as client:
            remote, _ = csv_text(tmp_path, "dask.csv", executor=client.get_executor())
            ex, close = sweep.executor_from_spec("dask://" + cluster.scheduler_address.split(
                "://", 1)[1])
            try:
                again, _ = csv_text(tmp_path, "dask2.csv", executor=ex)
            finally:
                close()
    assert remote == local == again


def test_unknown_key_is_refused():
    with pytest.raises(ScenarioError, match="unknown scenario key"):
        sweep.validate_points(sweep.grid_points({"fieldDefyance": [1]}))


def test_cli_sweep_writes_csv_and_plots(tmp_path, capsys):
    # --chunk: a sweep this small would run in this process without it
    # (sweep.SMALL_SWEEP_ROBOTS); here its chunks go to the worker processes
    rc = main(["sweep", "--grid", "sigRadius=3,6", "--grid", "movementModel=firefly,ant",
               "--seeds", "3", "--set", "maxTicks=3000", "--executor", "processes:2",
               "--chunk", "4", "--out", str(tmp_path)])
    assert rc == 0
    assert (tmp_path / "sweep.csv").read_text().count("\n") == 13
    assert (tmp_path / "by_sigRadius.png").stat().st_size > 1000
    assert (tmp_path / "by_movementModel.png").stat().st_size > 1000
    assert "12 runs" in capsys.readouterr().out


def test_cli_thesis_preset_small(tmp_path):
    rc = main(["sweep", "--thesis", "--seeds", "2", "--executor", "inline",
               "--set", "maxTicks=1500", "--out", str(tmp_path)])
    assert rc == 0
    for name in ("graph1", "graph2", "graph3", "graph4", "fig22_bar", "fig23_L_plus", "fig24_X"):
        assert (tmp_path / f"{name}.png").exists(), name


def test_cli_usage_errors(capsys):
    assert main(["sweep", "--grid", "agents="]) == 2          # a key without values
    assert main(["sweep", "--grid", "nope=1,2"]) == 2
    assert main(["sweep", "--grid", "agents=5", "--seeds", "x"]) == 2


def test_a_grid_over_behaviours_reports_each_behaviours_measures(tmp_path):
    """auto picks an engine per behaviour; every row equals the reference's
    and carries the measures its behaviour declares (spec.MEASURES)."""
    pts = sweep.grid_points({"behaviour": ["thesis", "aggregate"]})
    rows = sweep.sweep(pts, [1, 2], overrides=OVR)
    ref = sweep.sweep(pts, [1, 2], overrides=OVR, engine="reference")
    assert [{**r, "engine": "reference"} for r in rows] == ref
    agg = [r for r in rows if r["behaviour"] == "aggregate"]
    the = [r for r in rows if r["behaviour"] == "thesis"]
    assert len(agg) == len(the) == 2
    assert all(r["largest"] >= 1 and r["stopped"] >= r["largest"] for r in agg)
    assert all("largest" not in r for r in the)
    text = sweep.write_csv(rows, tmp_path / "b.csv").read_text().splitlines()
    header = text[0].split(",")
    assert header.count("largest") == 1 and "shape_iou" in header
    assert len(text) == 5


class CountedPool(ProcessPoolExecutor):
    """A process pool that counts the chunks it was given."""

    def __init__(self, *args, **kw):
        super().__init__(*args, **kw)
        self.chunks = 0

    def submit(self, *args, **kw):
        self.chunks += 1
        return super().submit(*args, **kw)


def test_a_small_sweep_runs_in_this_process_and_a_chunked_one_in_the_pool():
    """At most SMALL_SWEEP_ROBOTS robots in all and no chunk size: the runs
    are cheaper than a worker's start, its build and its load of the step,
    and run here; given a chunk size, the same sweep goes to the pool's
    workers. The rows are the same."""
    pts = sweep.grid_points({"sigRadius": [3, 6]})
    warm_step()
    inline = sweep.sweep(pts, SEEDS, overrides=OVR)
    with CountedPool(2) as pool:
        here = sweep.sweep(pts, SEEDS, overrides=OVR, executor=pool)
        assert pool.chunks == 0
        pooled = sweep.sweep(pts, SEEDS, overrides=OVR, executor=pool, chunk_size=2)
        assert pool.chunks == 3
    assert here == pooled == inline
    assert {r["engine"] for r in here} == {"soa"}


def test_the_small_sweep_bound_counts_every_run_robot_in_the_soa_engine():
    sc = sweep.point_scenarios(sweep.grid_points({}), overrides={"agents": 20})[0]
    with ProcessPoolExecutor(1) as pool:
        fits = [sc] * (sweep.SMALL_SWEEP_ROBOTS // 20)
        assert sweep._small(pool, "soa", fits)
        assert not sweep._small(pool, "soa", fits + [sc])
        assert not sweep._small(pool, "reference", fits)   # slow runs: the pool's cores help
    with ThreadPoolExecutor(1) as threads:
        assert not sweep._small(threads, "soa", fits)
    assert not sweep._small(None, "soa", fits)


def test_a_row_with_a_column_the_header_lacks_is_refused_by_name(tmp_path):
    with pytest.raises(ValueError, match=r"header lacks: \['extra'\]"):
        sweep.write_csv([{"seed": 1, "extra": 2}], tmp_path / "s.csv", names=["seed"])
    journal = sweep.CsvAppender(tmp_path / "j.csv", ["seed", "ticks"])
    journal.append([{"seed": 1}])                     # a missing column is an empty cell
    with pytest.raises(ValueError, match="header lacks"):
        journal.append([{"seed": 2, "extra": 3}])
    journal.close()
    assert (tmp_path / "j.csv").read_text() == "seed,ticks\n1,\n"


def test_the_journal_holds_the_file_only_of_its_own_rows_in_run_order(tmp_path):
    """The CLI writes sweep.csv again only when its journal is not already
    that file: rows appended afresh, the very rows, in run order."""
    names = ["seed", "ticks"]
    rows = [{"seed": s, "ticks": 10 * s} for s in (1, 2, 3, 4)]
    journal = sweep.CsvAppender(tmp_path / "j.csv", names)
    assert not journal.holds([])                         # no file yet: write_csv makes it
    journal.append(rows[:2])
    journal.append(rows[2:])
    journal.close()
    assert journal.holds(rows)
    assert (tmp_path / "j.csv").read_text() == \
        sweep.write_csv(rows, tmp_path / "w.csv", names).read_text()
    assert not journal.holds(rows[2:] + rows[:2])        # another order
    assert not journal.holds([dict(r) for r in rows])    # equal rows, not these
    assert not journal.holds(rows[:3])
    out_of_order = sweep.CsvAppender(tmp_path / "o.csv", names)
    out_of_order.append(rows[2:])
    out_of_order.append(rows[:2])
    out_of_order.close()
    assert not out_of_order.holds(rows)
    resumed = sweep.CsvAppender(tmp_path / "j.csv", names, resume=True)
    resumed.append([])
    resumed.close()
    assert not resumed.holds([])                         # the file holds rows from before


def test_sweep_csv_cells_are_each_values_text(tmp_path):
    import numpy as np
    row = {"a": None, "b": True, "c": 0.1 + 0.2, "d": np.float64(0.5), "e": "x,y", "f": 7,
           "g": np.int64(-3), "h": ""}
    path = sweep.write_csv([row, {"a": 1}], tmp_path / "s.csv")
    got = sweep.read_csv(path)
    assert got[0] == {k: sweep._cell(v) for k, v in row.items()}
    assert got[0]["d"] == "0.5" and got[0]["a"] == "" and got[0]["c"] == "0.30000000000000004"
    assert got[1] == {"a": "1", **{k: "" for k in "bcdefgh"}}


def test_the_journal_puts_chunks_that_returned_out_of_run_order_in_order(tmp_path):
    """A journal whose chunks came back out of run order is made the file
    write_csv writes from its own appends' texts; rows that are not its
    appends, each whole, leave it untouched (the CLI then writes every row)."""
    names = ["seed", "ticks", "x"]
    rows = [{"seed": s, "ticks": 10 * s, "x": [None, 0.1 + 0.2, "a,b"][s % 3]}
            for s in range(1, 8)]
    want = sweep.write_csv(rows, tmp_path / "w.csv", names).read_text()
    journal = sweep.CsvAppender(tmp_path / "j.csv", names)
    for block in (rows[5:], rows[:2], [], rows[2:5]):
        journal.append(block)
    journal.close()
    before = (tmp_path / "j.csv").read_text()
    assert before != want and sorted(before.splitlines()) == sorted(want.splitlines())
    for other in (rows[1:] + rows[:1], rows[:6], rows[:2] + rows[3:5] + rows[2:3] + rows[5:],
                  [dict(r) for r in rows], rows[:5] + rows[6:] + rows[5:6]):
        assert not journal.reorder(other)
        assert (tmp_path / "j.csv").read_text() == before
    assert not journal.holds(rows)
    assert journal.reorder(rows)
    assert (tmp_path / "j.csv").read_text() == want
    resumed = sweep.CsvAppender(tmp_path / "j.csv", names, resume=True)
    resumed.append(rows[:1])
    resumed.close()
    assert not resumed.reorder(rows[:1])                 # the file holds rows from before


ENTRY = """
import atexit, sys
from bridge import cli
main = cli.main

def command(argv):                      # a handler the command registers runs
    import os
    print("blas threads", os.environ.get("OPENBLAS_NUM_THREADS"))
    atexit.register(print, "handler ran")
    return main(argv)

class Freed:                            # freed by the interpreter's teardown only
    def __del__(self):
        print("teardown ran")

kept = Freed()
cli.main = command
sys.exit(cli.entry(sys.argv[1:]))
"""


@pytest.mark.parametrize("argv, status, blas", [
    (["--executor", "inline", "--no-plots", "--json"], 0, None),  # ends after its handlers
    (["--seeds", "x"], 2, "3"),                                    # refused: the usual exit
])
def test_the_console_script_exits_with_the_commands_status_and_whole_output(
        tmp_path, argv, status, blas):
    """bridge.cli.entry: a finished sweep's process ends after every atexit
    handler, its output flushed, without the interpreter's teardown; any
    other outcome exits as main's caller would. Its commands run with one
    BLAS thread unless the user's environment asks for more."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    if blas:
        env["OPENBLAS_NUM_THREADS"] = blas
    done = subprocess.run(
        [sys.executable, "-c", ENTRY, "sweep", "--seeds", "2", "--engine", "reference",
         "--set", "maxTicks=300", "--out", str(tmp_path), *argv],
        cwd=Path(__file__).resolve().parents[1], capture_output=True, text=True, timeout=300,
        env=env)
    assert done.returncode == status, done.stderr
    out = done.stdout.splitlines()
    assert out[0] == f"blas threads {blas or 1}"
    if status == 0:
        assert out[-1] == "handler ran"
        assert json.loads(out[-2])["runs"] == 2
        assert (tmp_path / "sweep.csv").read_text().count("\n") == 3
    else:
        assert out[-2:] == ["handler ran", "teardown ran"]


def test_a_soa_chunk_runs_with_the_collector_off_and_leaves_it_as_it_was(monkeypatch):
    """run_chunk's soa chunk: no collector pass inside (its runs make no
    garbage cycle), the collector's state as before after, the summaries
    those of the same runs with it on."""
    import gc

    from sim_backend.batch import soa
    warm_step()
    base = sweep.base_dict(None, OVR)
    jobs = [(base, dict(pt.params), s) for pt in sweep.grid_points(GRID)[:1] for s in SEEDS]
    seen = []
    real = soa.run_batch

    def spy(*a, **kw):
        seen.append(gc.isenabled())
        return real(*a, **kw)
    with_gc = real(sweep._scenarios(jobs), SEEDS, until="delivered")
    monkeypatch.setattr(soa, "run_batch", spy)
    assert gc.isenabled()
    assert sweep.run_chunk(jobs, "soa") == with_gc
    assert gc.isenabled() and seen == [False]
    gc.disable()
    try:
        sweep.run_chunk(jobs, "soa")
        assert not gc.isenabled()
    finally:
        gc.enable()
