"""The struct-of-arrays batch engine (sim_backend/batch/soa.py) runs the
behaviour's own source through the transform (sim_backend/batch/transform.py).
tests/test_batch_engine.py holds it to the differential harness (every
behaviour, model, object, mixed batches, the single-source test); here:
faults, both crowd rules, the robots written back, named errors for
constructs outside the transform, and a warm start from the on-disk cache in
a second process.
"""

import json
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from sim_backend import kernel, registry
from sim_backend.batch.soa import SoaEngine
from sim_backend.errors import CompileError
from sim_backend.scenario import validate
from tests.harness import assert_same, count_crowding, reference

ROOT = Path(__file__).resolve().parent.parent


def test_faults_identical():
    sc = validate({"maxTicks": 1500, "deathRate": 0.2, "deadlockRate": 0.1,
                   "ignoreFieldRate": 0.1, "ignoreHostRate": 0.1, "randomRate": 0.1,
                   "probeMiss": 0.1, "probeGhost": 0.02, "fieldNoise": 2})
    assert_same([sc] * 2, [1, 2])


@pytest.mark.parametrize("crowd", ["yield", "block"])
def test_both_crowd_rules_identical_in_a_dense_swarm(crowd, monkeypatch):
    """crowd "yield" (the default) and "block": 150 robots crowd the object,
    so robots stand in the carried group's way and (yield) step aside or
    (block) stop it; 400 ticks show the blocks (the yielding runs deliver
    sooner)."""
    sc = validate({"agents": 150, "crowd": crowd, "maxTicks": 1500 if crowd == "yield" else 400})
    scs, seeds = [sc, sc.replace(movementModel="ant")], [1, 2]
    with monkeypatch.context() as m:             # the transform reads the real kernel
        seen = count_crowding(m)
        refs = [reference(s, seed) for s, seed in zip(scs, seeds)]
    got = assert_same(scs, seeds, refs=refs)
    if crowd == "yield":
        assert all(r.delivered for r in got)
        assert seen["aside"] > 0, "no robot stepped aside: a weak comparison"
    else:
        assert seen["blocked"] > 0, "no robot blocked the group: a weak comparison"


def test_final_robots_are_the_reference_robots():
    """The arrays are written back into the CPython robots when they are
    first read, and not before: the summary and the comparisons above read
    none, so a sweep never pays for it."""
    sc = validate({"maxTicks": 600})
    ref = reference(sc, 4)
    got = assert_same([sc], [4], refs=[ref])[0]
    assert got.fill is not None
    robots = got.robots
    assert got.fill is None and got.robots is robots
    for a, b in zip(ref.robots, robots):
        va, vb = dict(vars(a)), dict(vars(b))
        assert vars(va.pop("rng")) == vars(vb.pop("rng"))
        assert va == vb


def _mutated_aggregate(tmp_path, name, anchor, insert):
    agg = registry.load("aggregate")
    copy = tmp_path / name
    shutil.copytree(agg.folder, copy, ignore=shutil.ignore_patterns("__pycache__"))
    robot = copy / "robot.py"
    src = robot.read_text()
    assert src.count(anchor) == 1, "the anchor of this test has moved; update the test"
    robot.write_text(src.replace(anchor, anchor + insert))
    return validate({"behaviour": str(copy)}), robot


def test_an_attribute_outside_the_subset_is_named(tmp_path):
    sc, _ = _mutated_aggregate(tmp_path, "aggregate_float",
                               "        self.rxbuf = [0, 0, 0, 0, 0, 0]\n",
                               "        self.gain = 0.5\n")
    with pytest.raises(CompileError, match=r"Robot\.gain: a float"):
        SoaEngine([(sc, 1)])


def test_arrays_that_share_memory_are_refused():
    """The compiled step's entry promises LLVM its arrays are apart
    (borrow.NoAlias): two array fields over one buffer are a named error,
    not a step that may read stale values (nothing is compiled)."""
    import numpy as np

    from sim_backend.batch import transform as T

    class Holder:
        def __init__(self) -> None:
            base = np.zeros(10, dtype=np.int64)
            self.a = base[:6]
            self.b = base[4:]

    layout = T.Layout()
    layout.add(Holder())
    for cl in layout.classes.values():
        cl.finish()
    with pytest.raises(CompileError, match="Holder__a and Holder__b share memory"):
        T.state_arrays(layout)


@pytest.mark.parametrize("construct,code,named", [
    ("try", "        try:\n            self.ticks += 0\n        except ValueError:\n"
            "            pass\n", "a Try statement"),
    ("list", "        self.ticks += len([1, 2])\n", "a List expression"),
    ("new object", "        Robot(1, 1, 0, 0, 0, 0)\n", "constructing a Robot"),
    ("unknown attribute", "        self.nowhere += 1\n", "a new attribute Robot.nowhere"),
])
def test_a_construct_outside_the_transform_is_named_with_its_line(tmp_path, construct, code,
                                                                   named):
    anchor = "    def step(self, hal):\n"
    sc, robot = _mutated_aggregate(tmp_path, "aggregate_" + construct.replace(" ", "_"),
                                   anchor, code)
    line = robot.read_text().split("\n").index(code.split("\n")[0]) + 1
    with pytest.raises(CompileError, match=f"robot.py:{line}: {named}"):
        SoaEngine([(sc, 1)])


def test_a_warm_build_reads_the_kept_text_and_an_edit_transforms_again(tmp_path, monkeypatch):
    """The generated text is kept (in this process and in the cache folder)
    with the files and names it was read from: a second build skips the
    transform, an edit of the behaviour's source or a patched function it
    calls does not (nothing here compiles: the engines are only built)."""
    from sim_backend import kernel
    from sim_backend.batch import soa
    monkeypatch.setenv("TOUCHSWARM_CACHE", str(tmp_path / "cache"))
    anchor = "    def step(self, hal):\n"
    # a no-op line: the copy's text is not aggregate's own, whose module (loaded
    # from this test's cache folder) the next aggregate batch would compile again
    sc, robot = _mutated_aggregate(tmp_path, "aggregate_kept", anchor,
                                   "        self.ticks -= 0\n")
    n = soa.transforms
    first = SoaEngine([(sc, 1)])
    assert soa.transforms == n + 1
    assert list((tmp_path / "cache" / "soa" / "generated").glob("*.json"))
    monkeypatch.setattr(soa, "_GENERATED", {})     # as a new process: from the folder
    again = SoaEngine([(sc, 2)])
    assert soa.transforms == n + 1 and again.compiled.digest == first.compiled.digest
    robot.write_text(robot.read_text().replace(anchor, anchor + "        self.ticks += 0\n"))
    edited = SoaEngine([(sc, 1)])
    assert soa.transforms == n + 2 and edited.compiled.digest != first.compiled.digest
    # the edit's store, checked as every table store the transform does not prove
    assert re.search(r"Robot__ints\[self, (\d+)\] = fits\(Robot__ints\[self, \1\] \+ 0\)",
                     edited.compiled.path.read_text())

    def counted(*a):                       # a patched kernel rule is read again, not kept
        return 0
    monkeypatch.setattr(kernel, "_chain", counted)
    with pytest.raises(CompileError, match=r"\.counted"):
        SoaEngine([(sc, 1)])


WARM = """
import json, sys
from sim_backend import sweep
from sim_backend.batch.soa import SoaEngine
from sim_backend.scenario import validate
sc = validate({"behaviour": "aggregate", "maxTicks": 50})
told = []
cold = sweep.warm([sc, sc], "auto", lambda b, d: told.append([b, str(d)]))
e = SoaEngine([(sc, 1)])
e.step()
s = e._tick_fn.stats
from sim_backend.batch import soa
print(json.dumps({"transforms": soa.transforms, "hits": sum(s.cache_hits.values()), "misses": sum(s.cache_misses.values()),
                  "xs": e.rb[0].tolist(), "dir": str(e.compiled.path.parent),
                  "cold": cold, "told": told}))
"""


def test_a_second_process_loads_the_compiled_step_from_the_disk_cache():
    # the suite's own cache: the first process compiles aggregate's step only
    # if no earlier test did (a cold compile is the same code path, and the
    # suite pays for it once); the second must load it from disk
    from sim_backend.batch.soa import cache_root
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    runs = []
    for _ in range(2):
        out = subprocess.run([sys.executable, "-c", WARM], env=env, capture_output=True,
                             text=True, check=True, cwd=ROOT)
        runs.append(json.loads(out.stdout.strip().splitlines()[-1]))
    first, warm = runs
    assert warm["hits"] >= 1 and warm["misses"] == 0
    assert warm["transforms"] == 0          # the generated text is kept too
    assert warm["xs"] == first["xs"]
    # sweep.warm compiles before the runs, and says so only when the cache lacks the step
    # (the first process may or may not have found it: another worker of the
    # suite can compile it meanwhile; what it said must match what it thought)
    if first["cold"]:
        assert first["cold"] == ["aggregate"] and first["told"] == [["aggregate", first["dir"]]]
    else:
        assert first["told"] == [] and first["misses"] == 0
    assert warm["cold"] == [] and warm["told"] == []
    assert Path(warm["dir"]).parent == cache_root() and warm["dir"] == first["dir"]
    assert list(Path(warm["dir"]).glob("__pycache__/*.nbi"))


def test_sweep_engine_soa_gives_the_reference_summaries():
    from sim_backend import sweep
    jobs = [({"maxTicks": 800}, {"fieldDefiance": 2}, seed) for seed in (1, 2)]
    got = sweep.run_chunk(jobs, engine="soa")
    assert sweep.run_chunk(jobs, engine="auto") == got      # auto is the soa engine
    assert sweep.pick_engine("auto") == "soa"
    sc = validate({"maxTicks": 800, "fieldDefiance": 2})
    assert got == [reference(sc, 1).summary(), reference(sc, 2).summary()]


def test_a_borrowed_array_is_the_same_memory_and_other_values_pass_through():
    import numpy as np
    from numba import njit

    from sim_backend.batch.borrow import borrow

    @njit
    def poke(a, k):
        b = borrow(a)
        b[1] = 7
        return b.sum() + borrow(k)

    a = np.zeros(4, dtype=np.int32)
    assert poke(a, 3) == 10
    assert a.tolist() == [0, 7, 0, 0]


def test_a_prefetch_takes_any_integer_index_and_changes_nothing():
    """borrow.prefetch of a 1-D element or a 2-D row, the index read from an
    int32 table as well as an int64 one (numba's own indexing widens both)."""
    import numpy as np
    from numba import njit

    from sim_backend.batch.borrow import prefetch

    @njit
    def fetch(flat, table, at):
        for k in range(len(at)):
            prefetch(flat, at[k])
            prefetch(table, at[k])
        return flat.sum() + table.sum()

    flat, table = np.arange(6), np.arange(12).reshape(3, 4)
    for dtype in (np.int32, np.int64):
        assert fetch(flat, table, np.array([2, 0], dtype=dtype)) == 15 + 66
    assert flat.tolist() == list(range(6)) and table.sum() == 66

def test_a_compiled_clear_zeroes_exactly_its_range_as_the_kernel_loop_does():
    """borrow.clear (kernel.clear compiled to a memset) zeroes a[lo:hi] of
    every element width the grids use and nothing outside it; an empty or
    reversed range changes nothing, as the kernel's loop."""
    import numpy as np
    from numba import njit

    from sim_backend import kernel
    from sim_backend.batch.borrow import clear

    @njit
    def zero(a, lo, hi):
        clear(a, lo, hi)

    for dtype in (np.int8, np.int16, np.int32, np.int64):
        for lo, hi in ((3, 9), (0, 12), (5, 5), (7, 2)):
            a = np.arange(1, 13, dtype=dtype)
            b = a.tolist()
            zero(a, lo, hi)
            kernel.clear(b, lo, hi)
            assert a.tolist() == b, (dtype, lo, hi)
            assert a.tolist() == [0 if lo <= k < hi else k + 1 for k in range(12)]



def test_the_robot_loop_is_inlined_and_its_entry_borrows_every_array(monkeypatch):
    """The two rules behind the soa engine's speed (docs/performance.md), read
    off the generated module (nothing is compiled): everything a robot's step
    reaches is inlined into the loop, the world's per-run functions are not,
    and the entry Python calls borrows every argument and promises LLVM its
    arrays are apart."""
    import ast

    monkeypatch.delenv("TOUCHSWARM_SOA_INLINE", raising=False)
    e = SoaEngine([(validate({"maxTicks": 50}), 1)])
    tree = ast.parse(e.compiled.path.read_text())
    inline, pipeline = {}, {}
    for f in tree.body:
        if isinstance(f, ast.FunctionDef):
            kw = {k.arg: k.value for k in f.decorator_list[0].keywords}
            inline[f.name] = ast.literal_eval(kw.get("forceinline", ast.Constant(False)))
            pipeline[f.name] = ast.unparse(kw["pipeline_class"]) if "pipeline_class" in kw else None
    for name in ("F_Robot_step", "F_Robot__search", "F_BatchBody_probe",
                 "F_sim_backend_kernel__probe", "F_Rng_below",
                 "F_sim_backend_batch_body__tick_all"):
        assert inline[name], name
    for name in ("F_sim_backend_kernel__apply_tick", "F_sim_backend_kernel__make_way"):
        assert not inline[name], name
    entry = next(f for f in tree.body if isinstance(f, ast.FunctionDef)
                 and f.name == e.compiled.names["tick_all"])
    call = entry.body[0].value
    assert [a.func.id for a in call.args] == ["borrow"] * len(entry.args.args)
    assert pipeline[entry.name] == "NoAlias"        # its arrays are apart (borrow.NoAlias)
    assert [a.args[0].id for a in call.args] == [a.arg for a in entry.args.args]


def test_inlining_can_be_turned_off_for_a_faster_cold_compile(monkeypatch):
    """TOUCHSWARM_SOA_INLINE=0 generates a different module (another cache
    entry) with nothing inlined."""
    monkeypatch.setenv("TOUCHSWARM_SOA_INLINE", "0")
    e = SoaEngine([(validate({"maxTicks": 50}), 1)])
    text = e.compiled.path.read_text()
    assert "forceinline" not in text and "borrow(" in text
    monkeypatch.delenv("TOUCHSWARM_SOA_INLINE")
    assert SoaEngine([(validate({"maxTicks": 50}), 1)]).compiled.digest != e.compiled.digest


TINY = '''
from numba import njit


@njit(cache=True)
def E_inc(a):
    return a + 1


E_inc__STATE = ()
'''

FIRST = """
import json, sys
from sim_backend.batch.soa import Compiled
c = Compiled(sys.argv[1], {"inc": "E_inc"})
fn, _ = c.entry("inc")
out = c.first_call(fn, (41,))
print(json.dumps({"out": out, "hits": sum(fn.stats.cache_hits.values()),
                  "dir": str(c.path.parent)}))
"""


def test_a_damaged_disk_cache_is_compiled_again_with_a_warning(tmp_path):
    """numba raises on a cache file it cannot unpickle; the soa engine's
    first call deletes that module's cache, says so, and compiles again."""
    env = {**os.environ, "TOUCHSWARM_CACHE": str(tmp_path), "PYTHONPATH": str(ROOT)}

    def run():
        out = subprocess.run([sys.executable, "-c", FIRST, TINY], env=env, capture_output=True,
                             text=True, check=True, cwd=ROOT)
        return json.loads(out.stdout.strip().splitlines()[-1]), out.stderr
    first, _ = run()
    cache = Path(first["dir"]) / "__pycache__"
    files = sorted(cache.glob("*.nb[ic]"))
    assert first["out"] == 42 and files
    for f in files:                                   # a truncated write, a bad disk
        f.write_bytes(f.read_bytes()[:10])
    again, err = run()
    assert again["out"] == 42 and again["hits"] == 0
    assert "could not be read" in err and str(cache) in err
    warm, err = run()
    assert warm["out"] == 42 and warm["hits"] == 1 and "could not be read" not in err


def test_an_error_that_is_not_the_cache_is_raised_and_the_cache_kept(tmp_path, monkeypatch):
    from sim_backend.batch.soa import Compiled
    monkeypatch.setenv("TOUCHSWARM_CACHE", str(tmp_path))
    c = Compiled(TINY + "\n# not loaded by another test\n", {"inc": "E_inc"})
    fn, _ = c.entry("inc")
    assert c.first_call(fn, (1,)) == 2
    cache = c.path.parent / "__pycache__"
    assert list(cache.glob("*.nbi"))

    def boom():
        raise ValueError("a bug in the step")
    with pytest.raises(ValueError, match="a bug in the step"):
        c.first_call(boom, ())
    assert list(cache.glob("*.nbi"))


@pytest.mark.parametrize("activation", ["sync", "netlogo"])
def test_a_big_run_fetched_ahead_is_the_reference(activation):
    """From kernel.WARM_MIN robots the compiled turn loops ask the cache for
    the patches (and under netlogo the robots' rows and objects) a few turns
    ahead (borrow.prefetch; no-ops in the reference): tick by tick the same
    run."""
    sc = validate({"agents": kernel.WARM_MIN, "worldSize": 24, "objectWeight": 3,
                   "activation": activation, "maxTicks": 8})
    assert_same([sc], [5])


def test_an_object_prefetch_is_a_prefetch_of_each_row():
    """kernel.prefetch of the HAL fetches robot k's element of each per-robot
    row the HAL views (its run, inbox head and tail); prefetch_held of the
    robots, the table row of the object robot k holds (its random stream),
    found through robot k's own row; read off the generated module (nothing
    compiles). Anything else is a named error."""
    from sim_backend.batch import body as B
    from sim_backend.batch import transform as T

    text = SoaEngine([(validate({"maxTicks": 50}), 1)]).compiled.path.read_text()
    loop = text[text.index("def F_sim_backend_kernel__go_iteration"):]
    loop = loop[:loop.index("\n\n\n")]
    fetched = re.findall(r"prefetch\(BatchBody__base0\[(\d+)\], a\)", loop)
    assert sorted(map(int, fetched)) == [B.RUN, B.IN_HEAD, B.IN_TAIL]
    assert re.search(r"\(prefetch\(Rng__ints, Robot__ints\[a, \d+\]\),\)", loop)
    with pytest.raises(CompileError, match="prefetch_held of a scalar"):
        T.generate(T.Layout(), {"f": (_prefetch_held_of_an_int, (T.SCALAR, T.SCALAR))})


def _prefetch_held_of_an_int(robots, k):
    kernel.prefetch_held(k, robots)
