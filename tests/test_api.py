"""The Python API (`import touchswarm`, docs/python-api.md): the same runs
and rows as the engines and the CLI, typed errors, and the doc's example
runs as written."""

import re
import sys
from importlib.metadata import version
from pathlib import Path

import pytest

import touchswarm
from bridge.cli import main
from perception.tracker import attach
from sim_backend import sweep as sw
from sim_backend.engine import Engine
from sim_backend.errors import ScenarioError
from sim_backend.scenario import load

DOC = Path(__file__).resolve().parent.parent / "docs" / "python-api.md"


def test_run_gives_the_engines_summary_ticks_and_world():
    r = touchswarm.run("ant", seed=5, fieldDefiance=3)
    sc = load("ant").replace(fieldDefiance=3)
    e = Engine(sc, 5)
    attach(e)                      # `touchswarm run` watches with a Perceiver too
    ref = e.run()
    assert r.summary == ref.summary()
    # the shape estimate and the verdict, as summary.json has them
    for k in ("estimate_iou", "recognised", "p"):
        assert k in r.summary and r.ticks.iloc[-1][k] in (r.summary[k], r.summary[k] or "")
    assert r.scenario == sc and r.seed == 5
    assert list(r.ticks["tick"]) == list(range(1, ref.ticks + 1))
    last = r.ticks.iloc[-1]
    assert last["power"] == r.summary["power"]
    assert last["shape_iou"] == r.summary["shape_iou"]
    states = [c for c in r.ticks.columns if c.startswith("n_")]
    assert (r.ticks[states].sum(axis=1) == sc.agents).all()
    assert sorted(r.world.object_cells) == sorted(ref.world.object_cells)


def test_run_takes_a_dict_and_a_toml_path(tmp_path):
    a = touchswarm.run({"agents": 8, "maxTicks": 300}, seed=2)
    assert a.summary["robots"] == 8 and a.summary["ticks"] <= 300
    f = tmp_path / "s.toml"
    f.write_text("agents = 8\nmaxTicks = 300\n")
    b = touchswarm.run(f, seed=2)
    assert b.summary == {**a.summary, "scenario": b.summary["scenario"]}


def test_ticks_are_dicts_without_pandas(monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)     # import pandas fails
    r = touchswarm.run(seed=1, maxTicks=50)
    assert isinstance(r.ticks, list) and r.ticks[0]["tick"] == 1
    assert r.ticks[-1]["power"] == r.summary["power"]
    rows = touchswarm.sweep({"fieldDefiance": [1, 4]}, seeds=[7], maxTicks=50)
    assert isinstance(rows, list) and [r["fieldDefiance"] for r in rows] == [1, 4]


def test_sweep_gives_the_rows_of_sweep_csv():
    df = touchswarm.sweep({"fieldDefiance": [1, 4], "movementModel": ["firefly", "ant"]},
                          seeds=2, maxTicks=400)
    rows = sw.sweep(sw.grid_points({"fieldDefiance": [1, 4],
                                    "movementModel": ["firefly", "ant"]}), [1, 2],
                    overrides={"maxTicks": 400})
    import pandas as pd
    # pandas holds a missing tick (None) as NaN: compare as frames
    pd.testing.assert_frame_equal(df, pd.DataFrame(rows))
    assert list(df.columns) == list(rows[0])


@pytest.mark.parametrize("call, message", [
    (lambda: touchswarm.run(fieldDefyance=3), "unknown key 'fieldDefyance'"),
    (lambda: touchswarm.run(seed=-1), "seed"),
    (lambda: touchswarm.run("nope"), "neither a built-in"),
    (lambda: touchswarm.run(42), "expected a built-in name"),
    (lambda: touchswarm.run(sigRadius=99), "sigRadius: 99 is outside"),
    (lambda: touchswarm.sweep({"sigRadius": 3}), "grid sigRadius: expected a list"),
    (lambda: touchswarm.sweep({"sigRadiuz": [3]}), "unknown scenario key"),
    (lambda: touchswarm.sweep({"sigRadius": [3]}, seeds=[1, 1]), "listed twice"),
    (lambda: touchswarm.sweep({"sigRadius": [3]}, engine="warp"), "engine"),
])
def test_bad_input_is_a_typed_error(call, message):
    with pytest.raises(ScenarioError, match=re.escape(message)):
        call()


def test_version_is_the_package_metadata_in_one_place(capsys):
    assert touchswarm.__version__ == version("touchswarm")
    with pytest.raises(SystemExit) as ex:
        main(["--version"])
    assert ex.value.code == 0
    assert capsys.readouterr().out.strip() == f"touchswarm {version('touchswarm')}"


def test_the_docs_worked_example_runs(tmp_path, monkeypatch, capsys):
    blocks = re.findall(r"```python\n(.*?)```", DOC.read_text(), re.S)
    assert blocks, "docs/python-api.md has no python block"
    monkeypatch.chdir(tmp_path)
    for code in blocks:
        exec(compile(code, str(DOC), "exec"), {"__name__": "__doc_example__"})
    out = capsys.readouterr().out
    assert "refused: overrides: unknown key 'fieldDefyance'" in out
