"""engine auto on a cold soa cache: the runs start at once in the reference
engine while the soa step compiles in another process, and the chunks
started after the compile ends run in soa.

No timing anywhere: the background compile is a fake the test ends when
it chooses (after the first chunk returned), or a real process the test
waits for."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from bridge.cli import main
from sim_backend import sweep
from sim_backend.batch.soa import SoaEngine
from sim_backend.scenario import Scenario, validate

ROOT = Path(__file__).resolve().parents[1]
MAX_TICKS = 300
GRID = {"sigRadius": [4, 6]}
SEEDS = [1, 2, 3]


def warm_folder() -> Path:
    """The folder of this machine's cache that holds the default behaviour's
    compiled step (compiled now if it does not: the soa tests need it anyway)."""
    sc = validate({"maxTicks": MAX_TICKS})
    sweep.warm([sc])
    folder = SoaEngine([(sc, 1)]).compiled.path.parent
    assert list(folder.glob("__pycache__/*.nbi"))
    return folder


# A sweep in a fresh process (so nothing compiled is in memory) with an empty
# $TOUCHSWARM_CACHE. The fake background compile ends when the first chunk's
# rows are in: "ok" copies a compiled step into the empty cache, as a real
# compile leaves it; "fail" ends with an error.
SCRIPT = r"""
import json, shutil, sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from sim_backend import sweep
from sim_backend.batch.soa import cache_root

mode, warm, executor = sys.argv[1], Path(sys.argv[2]), sys.argv[3]
grid, seeds, max_ticks = json.loads(sys.argv[4])
released, started, chunks, events = [False], [], [], []
# the generated source the sweep writes there anyway, as the warm cache has it:
# numba's index holds its source's mtime, read when the module is imported
dst = cache_root() / warm.name
dst.mkdir(parents=True)
shutil.copy2(warm / "mod.py", dst / "mod.py")

class Fake:
    pid = 4242
    error = None
    seconds = None

    def __init__(self, scenarios, claims):
        started.append(sorted({str(sc.behaviour) for sc in scenarios}))

    def finished(self):
        if not released[0]:
            return False
        if self.seconds is None:
            self.seconds = 61.0
            if mode == "fail":
                self.error = "TypingError: cannot unify int64 and none"
            else:
                shutil.copytree(warm / "__pycache__", dst / "__pycache__", dirs_exist_ok=True)
        return True

def on_rows(rows):
    chunks.append([r["engine"] for r in rows])
    released[0] = True

points = sweep.grid_points(grid)
ex = ProcessPoolExecutor(1) if executor == "processes" else None
cold_before = sorted(__import__("sim_backend.batch.soa", fromlist=["cold"]).cold(
    sweep.point_scenarios(points, overrides={"maxTicks": max_ticks})))
rows = sweep.sweep(points, seeds, overrides={"maxTicks": max_ticks}, chunk_size=2,
                   executor=ex, on_rows=on_rows, background=Fake,
                   on_event=lambda kind, text: events.append([kind, text]))
ref = sweep.sweep(points, seeds, overrides={"maxTicks": max_ticks}, engine="reference")
if ex is not None:
    ex.shutdown()
print(json.dumps({"rows": rows, "ref": ref, "chunks": chunks, "events": events,
                  "started": started, "cold_before": cold_before}, default=str))
"""


def background_sweep(tmp_path, mode, executor="inline"):
    env = {**os.environ, "TOUCHSWARM_CACHE": str(tmp_path / "cache"), "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", SCRIPT, mode, str(warm_folder()), executor,
                          json.dumps([GRID, SEEDS, MAX_TICKS])],
                         env=env, capture_output=True, text=True, cwd=tmp_path, timeout=900)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def same_but_engine(rows, ref):
    """Every run once, in point, seed order, equal to the reference in every
    column but `engine`."""
    assert [sweep.run_key(r) for r in rows] == [sweep.run_key(r) for r in ref]
    assert len({sweep.run_key(r) for r in rows}) == len(GRID["sigRadius"]) * len(SEEDS)
    for r, f in zip(rows, ref):
        assert {k: v for k, v in r.items() if k != "engine"} == \
            {k: v for k, v in f.items() if k != "engine"}
    assert {f["engine"] for f in ref} == {"reference"}


@pytest.mark.parametrize("executor", ["inline", "processes"])
def test_a_cold_cache_starts_in_the_reference_engine_and_moves_to_soa(tmp_path, executor):
    got = background_sweep(tmp_path, "ok", executor)
    assert got["cold_before"] == ["thesis"]          # the cache was empty
    assert got["started"] == [["thesis"]]            # one background compile
    same_but_engine(got["rows"], got["ref"])
    # the first chunk could not wait for the compile (the fake ends after
    # it): reference, and small; every chunk after it: soa
    first, *rest = got["chunks"]
    assert first == ["reference"] * len(first) and len(first) <= sweep.REFERENCE_CHUNK
    assert rest and all(e == "soa" for ch in rest for e in ch)
    assert [r["engine"] for r in got["rows"]].count("reference") == len(first)
    kinds = [k for k, _ in got["events"]]
    assert kinds == ["compiling", "compiled"]
    compiling, compiled = (t for _, t in got["events"])
    assert "runs start now in the reference engine" in compiling and "pid 4242" in compiling
    assert "compiled in the background in 1m01s" in compiled


def test_a_failed_compile_loses_no_run_and_says_why_in_one_line(tmp_path):
    got = background_sweep(tmp_path, "fail")
    same_but_engine(got["rows"], got["ref"])
    assert {r["engine"] for r in got["rows"]} == {"reference"}
    assert [k for k, _ in got["events"]] == ["compiling", "failed"]
    text = got["events"][1][1]
    assert "\n" not in text
    assert "TypingError: cannot unify int64 and none" in text
    assert "finishes in the reference engine" in text


# -- the real background process (waited for, never timed) --------------------------------------

def test_the_background_process_loads_a_step_the_cache_holds(tmp_path, monkeypatch):
    warm = warm_folder()
    shutil.copytree(warm, tmp_path / "soa" / warm.name)
    monkeypatch.setenv("TOUCHSWARM_CACHE", str(tmp_path))
    bg = sweep.BackgroundCompile([validate({"maxTicks": MAX_TICKS})] * 2)
    assert bg.behaviours == ["thesis"] and bg.pid > 0
    assert bg.wait() and bg.error is None and bg.seconds >= 0


def test_the_background_process_reports_its_failure_in_one_line(tmp_path):
    folder = tmp_path / "gone"
    from sim_backend import registry
    shutil.copytree(registry.load("aggregate").folder, folder,
                    ignore=shutil.ignore_patterns("__pycache__"))
    sc = Scenario(behaviour=str(folder))
    shutil.rmtree(folder)                             # the behaviour is gone by the compile
    bg = sweep.BackgroundCompile([sc])
    assert bg.wait()
    assert bg.error.startswith("ScenarioError: behaviour: ") and str(folder) in bg.error
    assert "not an installed behaviour" in bg.error
    assert "\n" not in bg.error


def test_a_behaviour_the_transform_refuses_runs_in_the_reference_engine(monkeypatch):
    from sim_backend.batch import soa
    from sim_backend.batch.transform import CompileError

    def refuse(scenarios):
        raise CompileError("robot.py:12: a try statement is outside the subset")
    monkeypatch.setattr(soa, "cold", refuse)
    events = []
    rows = sweep.sweep(sweep.grid_points({}), [1, 2], overrides={"maxTicks": MAX_TICKS},
                       on_event=lambda kind, text: events.append((kind, text)))
    assert [r["engine"] for r in rows] == ["reference", "reference"]
    assert [k for k, _ in events] == ["failed"]
    assert "CompileError: robot.py:12: a try statement" in events[0][1]


# -- what the CLI and the Python API show ----------------------------------------------------------

class Held:
    """A background compile that ends when the test says."""
    pid = 777
    error = None
    seconds = None
    done = False

    def __init__(self, scenarios, claims=None):
        pass

    def finished(self):
        if Held.done and self.seconds is None:
            self.seconds = 95.0
        return Held.done


@pytest.fixture
def cold_cache(monkeypatch, tmp_path):
    """This process sees the soa step as not compiled yet and the compile as
    Held; the step this machine's cache holds stands in for the compiled one."""
    from sim_backend.batch import soa
    warm_folder()
    monkeypatch.setattr(soa, "cold", lambda scs: {"thesis": tmp_path / "soa" / "x"})
    monkeypatch.setattr(sweep, "BackgroundCompile", Held)
    Held.done = False
    return Held


def test_cli_shows_the_background_compile_and_the_engine_of_each_row(tmp_path, capsys,
                                                                       cold_cache, monkeypatch):
    real = sweep.make_row

    def make_row(*args, **kw):                       # the compile ends with the first row
        row = real(*args, **kw)
        cold_cache.done = True
        return row
    monkeypatch.setattr(sweep, "make_row", make_row)
    assert main(["sweep", "--grid", "sigRadius=4,6", "--seeds", "3", "--set",
                 f"maxTicks={MAX_TICKS}", "--executor", "inline", "--chunk", "2",
                 "--no-plots", "--out", str(tmp_path)]) == 0
    cap = capsys.readouterr()
    err = cap.err.splitlines()
    assert err[0].startswith("sweep: the soa engine for behaviour 'thesis' is not compiled yet")
    assert "pid 777" in err[0]
    assert err[1].startswith("sweep: 1/6 runs (17%)")
    assert "; reference engine while soa compiles in the background (" in err[1]
    assert any(ln.startswith("sweep: the soa engine compiled in the background in 1m35s")
               for ln in err)
    assert err[-1].endswith("; soa engine (compiled in the background)")
    assert "6 runs (2 points x 3 seeds, 2 reference + 4 soa (auto) engine" in cap.out
    saved = sweep.read_csv(tmp_path / "sweep.csv")
    assert [r["engine"] for r in saved] == ["reference"] * 2 + ["soa"] * 4


def test_cli_engine_soa_waits_for_the_compile(tmp_path, capsys, cold_cache):
    assert main(["sweep", "--seeds", "2", "--set", f"maxTicks={MAX_TICKS}", "--engine", "soa",
                 "--executor", "inline", "--no-plots", "--out", str(tmp_path)]) == 0
    cap = capsys.readouterr()
    assert "in the background" not in cap.err
    assert [r["engine"] for r in sweep.read_csv(tmp_path / "sweep.csv")] == ["soa", "soa"]


def test_api_progress_tells_the_background_compile_from_the_first_line(cold_cache):
    import touchswarm
    lines = []
    rows = touchswarm.sweep({"sigRadius": [4]}, seeds=2, maxTicks=MAX_TICKS,
                            progress=lines.append)
    engines = rows["engine"].tolist() if hasattr(rows, "columns") else \
        [r["engine"] for r in rows]
    assert engines == ["reference", "reference"]     # Held never ends here
    assert lines[0].startswith("sweep: the soa engine for behaviour 'thesis' is not compiled")
    assert lines[1].startswith("sweep: 1/2 runs (50%)")
    assert "reference engine while soa compiles in the background" in lines[1]
    assert lines[-1].startswith("sweep: the soa compile goes on in the background (pid 777)")


def test_a_compile_another_sweep_runs_is_watched_not_started_again(tmp_path, monkeypatch):
    """While another process holds the step's compile lock, a second sweep
    starts no compile of its own: it runs in the reference engine until the
    lock is free and the step is on disk, then in soa."""
    from contextlib import ExitStack

    from sim_backend.batch import soa
    warm_folder()
    folder = tmp_path / "soa" / "x"
    stack = ExitStack()
    stack.enter_context(soa.compile_lock(folder))      # "another sweep" compiles
    assert soa.lock_holder(folder) == os.getpid()
    compiled = [False]
    monkeypatch.setattr(soa, "cold", lambda scs: {} if compiled[0] else {"thesis": folder})

    def on_rows(rows):                                 # it ends after the first chunk
        compiled[0] = True
        stack.close()

    def no_second_compile(scenarios, claims):
        raise AssertionError("a second compile was started")
    events = []
    rows = sweep.sweep(sweep.grid_points({}), [1, 2, 3], overrides={"maxTicks": MAX_TICKS},
                       chunk_size=2, on_rows=on_rows, background=no_second_compile,
                       on_event=lambda kind, text: events.append((kind, text)))
    assert soa.lock_holder(folder) is None
    assert [r["engine"] for r in rows] == ["reference", "reference", "soa"]
    assert [k for k, _ in events] == ["compiling", "compiled"]
    assert f"pid {os.getpid()}" in events[0][1]


def test_two_sweeps_that_find_the_step_missing_at_once_start_one_compile(tmp_path,
                                                                          monkeypatch):
    """A sweep claims the step's compile lock without waiting before it
    starts a compile; the claim, not a look at who holds the lock, decides.
    Here the other sweep's compile holds the lock but the look comes too
    early to see it (as when both sweeps looked before either compile
    began): this sweep still starts none, and watches the other's."""
    from sim_backend.batch import soa
    warm_folder()
    folder = tmp_path / "soa" / "x"
    other = soa.claim_lock(folder)                     # the other sweep's claim
    compiled = [False]
    monkeypatch.setattr(soa, "cold", lambda scs: {} if compiled[0] else {"thesis": folder})
    real = soa.lock_holder
    looks = []

    def too_early(f):
        looks.append(f)
        return None if len(looks) == 1 else real(f)
    monkeypatch.setattr(soa, "lock_holder", too_early)

    def on_rows(rows):
        compiled[0] = True
        other.close()

    def no_second_compile(scenarios, claims):
        raise AssertionError("a second compile was started")
    rows = sweep.sweep(sweep.grid_points({}), [1, 2, 3], overrides={"maxTicks": MAX_TICKS},
                       chunk_size=2, on_rows=on_rows, background=no_second_compile)
    assert [r["engine"] for r in rows] == ["reference", "reference", "soa"]


def test_the_compile_a_sweep_starts_is_handed_the_lock_it_claimed(tmp_path, monkeypatch):
    from sim_backend.batch import soa
    warm_folder()
    folder = tmp_path / "soa" / "x"
    monkeypatch.setattr(soa, "cold", lambda scs: {"thesis": folder})
    seen = []

    class Started(Held):
        def __init__(self, scenarios, claims):
            seen.append((list(claims), soa.lock_holder(folder), soa.claim_lock(folder)))
    Held.done = True
    sweep.sweep(sweep.grid_points({}), [1], overrides={"maxTicks": MAX_TICKS},
                background=Started)
    assert seen == [([folder], os.getpid(), None)]     # claimed, held while it starts
    assert soa.lock_holder(folder) is None             # the sweep's copy closed after


def test_a_cache_without_room_for_the_lock_still_compiles_in_the_background(monkeypatch):
    from sim_backend.batch import soa
    warm_folder()
    monkeypatch.setattr(soa, "cold", lambda scs: {"thesis": Path("/read-only/soa/x")})

    def unwritable(folder):
        raise PermissionError(13, "Permission denied", str(folder))
    monkeypatch.setattr(soa, "claim_lock", unwritable)
    started = []

    class Started(Held):
        def __init__(self, scenarios, claims):
            started.append(dict(claims))
    Held.done = False
    rows = sweep.sweep(sweep.grid_points({}), [1], overrides={"maxTicks": MAX_TICKS},
                       background=Started)
    assert started == [{}]
    assert [r["engine"] for r in rows] == ["reference"]
