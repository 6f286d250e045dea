"""docs/outputs.md defines every column of every file the tool writes. The
columns are taken from the code (a real run's summary and records, the
sweep's and the trace's column lists for every behaviour), so a column
added without docs fails here."""

import csv
import re
from pathlib import Path

import pytest

from sim_backend import registry
from sim_backend import params, sweep, trace
from sim_backend.engine import Engine
from sim_backend.records import write_records
from sim_backend.scenario import Scenario

ROOT = Path(__file__).resolve().parent.parent
DOC = (ROOT / "docs" / "outputs.md").read_text()
BEHAVIOURS = sorted(registry.names())


def section(title: str) -> str:
    """The text of one '## title' section (up to the next '## ')."""
    m = re.search(rf"^## {re.escape(title)}.*?$(.*?)(?=^## |\Z)", DOC, re.M | re.S)
    assert m, f"docs/outputs.md has no section '## {title}'"
    return m.group(1)


def documented(text: str) -> set[str]:
    """Every `name` in backticks, commas inside one pair split too."""
    names: set[str] = set()
    text = re.sub(r"```.*?```", "", text, flags=re.S)      # examples are no definitions
    for code in re.findall(r"`([^`]+)`", text):
        names.update(n.strip() for n in code.split(","))
    return names


@pytest.fixture(scope="module", params=BEHAVIOURS)
def finished(request, tmp_path_factory):
    sc = Scenario(behaviour=request.param, maxTicks=200)
    result = Engine(sc, 1).run()
    out = tmp_path_factory.mktemp(request.param)
    return result, write_records(result, out)


def test_every_summary_key_is_documented(finished):
    result, _ = finished
    # the behaviour's parameters are one documented group (scenarios --behaviour)
    missing = (set(result.summary()) - documented(section("summary.json"))
               - set(params.names(result.scenario.behaviour)))
    assert not missing, f"summary.json keys missing from docs/outputs.md: {sorted(missing)}"


def test_every_run_csv_column_is_documented(finished):
    result, paths = finished
    text = section("The run CSVs")
    rows = {(m.group(1), c) for m in re.finditer(r"^\| `([a-z]+\.csv)` \|(.*)$", text, re.M)
            for c in documented(m.group(2).split("|")[0])}
    csvs = [p for p in paths if p.suffix == ".csv"]
    # the thesis's load and shape files only for a behaviour that has them
    thesis = str(result.scenario.behaviour) == "thesis"
    assert sorted(p.name for p in csvs) == (["ct.csv", "indstats.csv", "shape.csv", "tt.csv"]
                                             if thesis else ["indstats.csv", "tt.csv"])
    for p in csvs:
        with p.open() as f:
            header = next(csv.reader(f))
        missing = [c for c in header if (p.name, c) not in rows and c != "seed"]
        assert not missing, f"{p.name} columns missing from docs/outputs.md: {missing}"
    assert ("indstats.csv", "seed") in rows


def test_every_sweep_csv_column_is_documented():
    names = sweep.columns(BEHAVIOURS)
    text = section("sweep.csv")
    # scenario keys are one documented group, each key defined in scenarios.md
    scenario_doc = documented((ROOT / "docs" / "scenarios.md").read_text())
    own = {n for b in BEHAVIOURS for n in params.names(b)}
    missing = [c for c in names if c not in documented(text)
               and not (c in sweep.SCENARIO_KEYS and c in scenario_doc) and c not in own]
    assert not missing, f"sweep.csv columns missing from the docs: {missing}"
    rows = sweep.sweep(sweep.grid_points({"behaviour": BEHAVIOURS}), [1],
                       overrides={"maxTicks": 100}, engine="reference")
    # the list the doc is checked against is what the rows really hold
    # (a row holds its own behaviour's parameters only: compare as sets)
    assert {k for r in rows for k in r} == set(names)


def test_every_trace_column_is_documented():
    text = section("The per-tick trace")
    for b in BEHAVIOURS:
        missing = [c for c, _ in trace.columns(registry.load(b)) if c not in documented(text)]
        assert not missing, f"trace columns of {b} missing from docs/outputs.md: {missing}"


def test_every_experiment_key_is_documented():
    from bridge.commands import experiment
    text = section("sweep.csv")
    keys = {k for k in documented(text)} | {m for m in re.findall(r"`\[(\w+)\]`", text)}
    missing = [k for k in experiment.KEYS if k not in keys]
    assert not missing, f"experiment file keys missing from docs/outputs.md: {missing}"
