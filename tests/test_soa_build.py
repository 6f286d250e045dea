"""Building the soa engine on a warm machine: the generated text kept per
source tree, the compile lock a sweep claims and hands to its background
compile, and a cached step loaded without numba's compile-only set-up.
Nothing here compiles a step: the loads use the suite's compiled one."""

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from sim_backend.batch import soa
from sim_backend.scenario import validate

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("sim_backend", "firmware_logic", "perception")


def child(code: str, *args: str, cwd: Path = ROOT, **env: str) -> dict:
    """The last line of a fresh interpreter running `code`, as JSON."""
    out = subprocess.run([sys.executable, "-c", code, *args], cwd=cwd, capture_output=True,
                         text=True, env={**os.environ, "PYTHONPATH": str(cwd), **env})
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


# -- the generated text, kept per source tree ------------------------------------------------

BUILD = """
import json
from sim_backend.batch import soa
from sim_backend.scenario import validate
e = soa.SoaEngine([(validate({"maxTicks": 5}), 1)])
print(json.dumps({"transforms": soa.transforms, "digest": e.compiled.digest}))
"""


def test_two_source_trees_sharing_a_cache_each_keep_their_generated_text(tmp_path):
    """A second checkout (or an install beside a clone) using the same
    cache reads its own kept text, as the first does: neither build
    transforms again after the other's (one key for both had each tree's
    build overwrite the other's). The texts are equal, so both trees load
    one compiled step."""
    tree = tmp_path / "tree"
    for name in PACKAGES:
        shutil.copytree(ROOT / name, tree / name, ignore=shutil.ignore_patterns("__pycache__"))
    cache = str(tmp_path / "cache")
    runs = [child(BUILD, cwd=t, TOUCHSWARM_CACHE=cache) for t in (ROOT, tree, ROOT, tree)]
    assert [r["transforms"] for r in runs] == [1, 1, 0, 0]
    assert len({r["digest"] for r in runs}) == 1
    assert len(list((tmp_path / "cache" / "soa" / "generated").glob("*.json"))) == 2


# -- the compile lock: claimed without waiting, handed to the compile's process --------------

def test_a_claim_fails_while_another_holds_the_lock_and_names_the_claimer(tmp_path):
    folder = tmp_path / "step"
    with soa.compile_lock(folder):                  # a fake compile in "another process"
        assert soa.claim_lock(folder) is None
    mine = soa.claim_lock(folder)
    assert mine is not None and soa.lock_holder(folder) == os.getpid()
    assert soa.claim_lock(folder) is None           # one claim at a time
    mine.close()
    assert soa.lock_holder(folder) is None


HOLD = """
import json, sys
from pathlib import Path
from sim_backend.batch import soa
soa.adopt_lock(Path(sys.argv[1]), int(sys.argv[2]))
print("held", flush=True)
sys.stdin.readline()                             # until the test lets it end
"""


def test_a_claimed_lock_handed_to_a_child_is_held_until_the_child_ends(tmp_path):
    """The sweep claims the lock, starts its background compile with the
    lock's file, and closes its own copy: the child holds the lock (and
    names itself) for as long as it lives, the sweep's end frees nothing."""
    folder = tmp_path / "step"
    claim = soa.claim_lock(folder)
    assert claim is not None
    proc = subprocess.Popen([sys.executable, "-c", HOLD, str(folder), str(claim.fileno())],
                            cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)},
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True,
                            pass_fds=[claim.fileno()])
    claim.close()
    assert proc.stdout.readline().strip() == "held"
    assert soa.lock_holder(folder) == proc.pid
    assert soa.claim_lock(folder) is None
    proc.communicate("\n")
    assert proc.returncode == 0
    assert soa.lock_holder(folder) is None


def test_a_process_handed_the_lock_compiles_under_it_without_waiting_on_itself(tmp_path,
                                                                                monkeypatch):
    import fcntl
    folder = tmp_path / "step"
    claim = soa.claim_lock(folder)
    monkeypatch.setattr(soa, "_HELD", {})
    soa.adopt_lock(folder, os.dup(claim.fileno()))
    claim.close()
    calls = []
    real = fcntl.flock
    monkeypatch.setattr(fcntl, "flock", lambda f, op: (calls.append(op), real(f, op))[1])
    with soa.compile_lock(folder):                  # would wait for ever on its own lock
        assert soa.lock_holder(folder) == os.getpid()
    assert not [op for op in calls if op == fcntl.LOCK_EX]
    soa._HELD.pop(folder).close()
    assert soa.lock_holder(folder) is None


# -- a cached step loaded without the compile-only set-up -------------------------------------

LOAD = """
import json
from numba.core import base
from sim_backend.batch.soa import SoaEngine
from sim_backend.scenario import validate
refreshes = [0]
real = base.BaseContext.refresh
def counted(self):
    refreshes[0] += 1
    return real(self)
base.BaseContext.refresh = counted
e = SoaEngine([(validate({"maxTicks": 40}), 3)], record_trajectories=True)
e.run()
s = e._tick_fn.stats
print(json.dumps({"refreshes": refreshes[0], "misses": sum(s.cache_misses.values()),
                  "hits": sum(s.cache_hits.values()), "summary": e.results[0].summary(),
                  "states": e.results[0].states[-1]}, default=str))
"""


def test_a_cached_step_loads_without_numbas_compile_set_up_and_runs_the_same():
    """numba refreshes its typing and lowering registries before it loads
    a cached entry; only a compile reads them. The step (and the states
    entry a recording run loads) load without that refresh and give the
    reference's run."""
    from sim_backend import sweep
    from sim_backend.engine import Engine
    sc = validate({"maxTicks": 40})
    sweep.warm([sc])                     # the suite's compiled step (compiled once if missing)
    got = child(LOAD)
    assert got["hits"] >= 1 and got["misses"] == 0
    assert got["refreshes"] == 0
    ref = Engine(sc, 3, record_trajectories=True).run()
    assert got["summary"] == json.loads(json.dumps(ref.summary(), default=str))
    assert got["states"] == ref.states[-1]


class FakeCache:
    """numba's cache object, as far as _loading_only reads it."""

    def __init__(self):
        self.loaded = []

    def load_overload(self, sig, ctx):
        raise AssertionError("the refreshing load ran")

    def _load_overload(self, sig, ctx):
        self.loaded.append(sig)
        return None                      # a miss: numba compiles (and refreshes) itself

    def _guard_against_spurious_io_errors(self):
        from contextlib import nullcontext
        return nullcontext()


class FakeDispatcher:
    def __init__(self, cache):
        self._cache = cache

    def __call__(self, sig):
        return self._cache.load_overload(sig, object())


def test_loading_only_goes_around_the_refresh_and_leaves_the_cache_as_it_was(monkeypatch):
    from numba.core import runtime
    inits = []
    monkeypatch.setattr(runtime.rtsys, "initialize", inits.append)
    cache = FakeCache()
    fn = FakeDispatcher(cache)
    with soa._loading_only(fn):
        assert fn("sig") is None
    assert cache.loaded == ["sig"] and len(inits) == 1     # the runtime a loaded step calls
    assert "load_overload" not in vars(cache)
    with pytest.raises(AssertionError, match="the refreshing load ran"):
        fn("sig")


def test_loading_only_leaves_a_cache_it_does_not_know_alone():
    """Another numba's cache (no _load_overload) or a plain function: the
    call is made as it is."""
    class Other:
        def load_overload(self, sig, ctx):
            return "loaded by numba"
    fn = FakeDispatcher(Other())
    with soa._loading_only(fn):
        assert fn("sig") == "loaded by numba"
    with soa._loading_only(len):
        assert len("ab") == 2


FREEZE = """
import atexit, gc, json
from sim_backend.batch import soa
registered = []
atexit.register = lambda fn, *a: registered.append(fn) or fn
c = soa.Compiled("inc__STATE = ()\\ndef inc(x):\\n    return x + 1\\n", {"inc": "inc"})
fn, _ = c.entry("inc")
c.first_call(fn, (1,))
c.first_call(fn, (2,))
print(json.dumps({"freezes": sum(f is gc.freeze for f in registered)}))
"""


def test_a_process_that_loaded_a_step_freezes_its_heap_at_exit(tmp_path):
    """The interpreter's last collections would walk numba's heap; the
    first call of a step registers gc.freeze for the exit, once."""
    got = child(FREEZE, TOUCHSWARM_CACHE=str(tmp_path))
    assert got["freezes"] == 1


NUMBA_IMPORT = """
import json, sys
sys.path.insert(0, sys.argv[1])
from sim_backend.batch import soa
soa._without("numba", soa.CFFI)
from numba.core import config
print(json.dumps({"yaml": "yaml" in sys.modules, "numba": "numba" in sys.modules,
                  "quiet": config.DISABLE_PERFORMANCE_WARNINGS}))
"""


def test_numba_imports_yaml_only_to_read_a_config_file_that_is_there(tmp_path):
    """yaml is numba's only to read .numba_config.yaml from the working
    directory: without the file numba is imported with yaml blocked, with it
    numba reads it as before (yaml present: dask's extra brings it)."""
    pytest.importorskip("yaml")
    bare = child(NUMBA_IMPORT, str(ROOT), cwd=tmp_path)
    assert bare == {"yaml": False, "numba": True, "quiet": 0}
    (tmp_path / soa.NUMBA_CONFIG_FILE).write_text("disable_performance_warnings: 1\n")
    configured = child(NUMBA_IMPORT, str(ROOT), cwd=tmp_path)
    assert configured == {"yaml": True, "numba": True, "quiet": 1}


@pytest.mark.parametrize("dtype", ["int8", "int16", "int32"])
@pytest.mark.parametrize("values", [[0, 3, 0, 127], [0, 128, 255], [2, -1, 0], [0, 256], [1, 70000],
                                    [True, 0], [1.0, 2]])
def test_a_grid_converts_as_its_list_would(dtype, values):
    """BatchArrays hands a grid to numpy as bytes when it can: the array is
    the list's, and a value the grid's type cannot hold is refused as the
    list is (numpy's OverflowError), never wrapped."""
    import numpy as np
    want, got = np.zeros(len(values), dtype=dtype), np.zeros(len(values), dtype=dtype)
    try:
        want[:] = values
    except OverflowError:
        with pytest.raises(OverflowError):
            got[:] = soa._small_ints(values, got.dtype)
        return
    got[:] = soa._small_ints(values, got.dtype)
    assert got.tolist() == want.tolist()


def test_a_forked_worker_takes_its_parents_check_of_the_kept_text_once(monkeypatch):
    """A sweep's forked worker builds on the text its parent checked (or
    made) without checking every source file again; its next build checks,
    as every build of the parent does."""
    sc = validate({"maxTicks": 5})
    soa.SoaEngine([(sc, 1)])                       # the parent's check
    checks: list[int] = []
    hold = soa.T.Inputs.hold
    monkeypatch.setattr(soa.T.Inputs, "hold", lambda self: checks.append(1) or hold(self))
    soa.SoaEngine([(sc, 1)])
    assert checks == [1]                           # the parent's own builds check
    read, write = os.pipe()
    pid = os.fork()
    if pid == 0:                                   # the worker
        try:
            got = []
            for _ in range(2):
                before = len(checks)
                soa.SoaEngine([(sc, 2)])
                got.append(len(checks) - before)
            os.write(write, json.dumps([got, soa.transforms]).encode())
        finally:
            os._exit(0)
    os.close(write)
    with os.fdopen(read) as f:
        got, transforms = json.loads(f.read())
    os.waitpid(pid, 0)
    assert got == [0, 1] and transforms == soa.transforms


def _generation_of(obj: object) -> int | None:
    import gc
    for g in range(3):
        if any(o is obj for o in gc.get_objects(generation=g)):
            return g
    return None


def test_a_builds_objects_leave_the_youngest_generation_at_its_end():
    import gc
    assert gc.isenabled()
    e = soa.SoaEngine([(validate({"agents": 8}), s) for s in (1, 2)])
    young = gc.get_count()[0]           # objects made since the youngest's last pass
    # the collector's next pass does not walk the whole build
    assert young < 100 < len(e.robot_objs) * 10
    assert _generation_of(e.robot_objs[-1]) == 2 and _generation_of(e.worlds[-1]) == 2
    assert gc.isenabled()


def test_a_build_beside_a_step_leaves_the_heap_frozen_to_the_steps_end(monkeypatch):
    import gc
    frozen = gc.get_freeze_count()
    monkeypatch.setattr(soa, "_STEPPING", [1])        # a step runs in another thread
    try:
        e = soa.SoaEngine([(validate({"agents": 8}), 1)])
        assert gc.get_freeze_count() > frozen and _generation_of(e.robot_objs[0]) is None
    finally:
        gc.unfreeze()                                   # what that step's end does
    assert _generation_of(e.robot_objs[0]) == 2
