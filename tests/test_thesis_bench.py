"""The tables of docs/thesis-reproduction.md that a command produces are
produced by a bench script: the claims table is exactly what
bench/thesis_claims.py renders from its committed statistics; the options
and Appendix A tables have the rows and columns bench/thesis_options.py and
bench/appendix_a.py print, which run here in a tiny mode (one or two seeds,
the reference engine, a few ticks) so they cannot rot."""

from __future__ import annotations

import csv
import importlib.util
import json
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "thesis-reproduction.md"


def _bench(name: str):
    spec = importlib.util.spec_from_file_location(f"bench_{name}", ROOT / "bench" / f"{name}.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _block(script: str, args: str = "") -> str:
    text = DOC.read_text()
    begin, end = f"<!-- bench/{script}.py{args}: begin -->", f"<!-- bench/{script}.py{args}: end -->"
    assert text.count(begin) == 1 and text.count(end) == 1, script
    return text.split(begin, 1)[1].split(end, 1)[0].strip()


def _table(text: str) -> list[list[str]]:
    """The markdown table's rows (header first, the --- line dropped) as cells."""
    rows = [line.strip().strip("|").split(" | ") for line in text.splitlines()
            if line.startswith("|")]
    return [[c.strip() for c in r] for r in rows if not set("".join(r)) <= set("-| ")]


def test_the_claims_table_is_what_the_script_renders_from_its_statistics() -> None:
    claims = _bench("thesis_claims")
    data = json.loads((ROOT / "bench" / "thesis_claims.json").read_text())
    assert _block("thesis_claims") == claims.render(data)
    assert data["claims"] == claims.claims(data["points"])
    verdicts = {c["verdict"] for c in data["claims"]}
    assert verdicts <= {"holds", "does not hold", "depends on the time unit"} | {
        v for v in verdicts if v.startswith("holds for ")}
    # every claim the issue names has its row
    text = " ".join(c["claim"] for c in data["claims"])
    for words in ("Graph 1a", "Graph 1b", "Graph 2", "Graph 3", "Graph 4", "rPower 1.25",
                  "firefly robots converge quicker", "more robots", "Figures 22-24"):
        assert words in text, words


def _rows(tmp_path: Path) -> Path:
    """A small synthetic sweep.csv: firefly's time rises with fieldDefiance
    in robot moves only, the ant's in neither; sigRadius and rPower speed
    both up; the holder polygon improves with N."""
    rows = []
    for seed in range(1, 6):
        jitter = seed - 3
        for m, base in (("firefly", 50), ("ant", 200)):
            for fd in (0, 1, 2, 4):
                it = None if fd == 0 and seed < 3 else base + jitter
                mv = None if it is None else it * (1 + fd)
                rows.append({"experiment": "graph1", "movementModel": m, "fieldDefiance": fd,
                             "converged_tick": it, "converged_moves": mv})
            for r in (1, 5, 9):
                rows.append({"experiment": "graph2", "movementModel": m, "sigRadius": r,
                             "converged_tick": base * 10 / r + jitter,
                             "converged_moves": base * 12 / r + jitter})
            for p, req in (("0.5", 10), ("1.0", 5), ("1.25", 4), ("1.5", 4), ("5.0", 1)):
                rows.append({"experiment": "graph3", "movementModel": m, "rPower": p,
                             "required": req, "converged_tick": base * req + jitter,
                             "converged_moves": base * req + jitter})
            for n in (10, 20, 40):
                rows.append({"experiment": "scalability", "movementModel": m, "agents": n,
                             "converged_tick": base * 40 / n + jitter,
                             "converged_moves": base * 40 / n + jitter})
        for obj in ("bar", "L", "cross", "X"):
            for n in (4, 8, 12):
                rows.append({"experiment": "shapes", "movementModel": "firefly", "object": obj,
                             "required": n, "converged_tick": 50, "converged_moves": 50,
                             "polygon_iou": n / 20 + jitter / 100, "shape_iou": 0.4})
    names = ["experiment", "movementModel", "object", "fieldDefiance", "sigRadius", "rPower",
             "agents", "required", "seed", "maxTicks", "converged_tick", "converged_moves",
             "polygon_iou", "shape_iou"]
    path = tmp_path / "sweep.csv"
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, names)
        w.writeheader()
        for i, r in enumerate(rows):
            r.setdefault("object", "bar")
            r.setdefault("required", 5)
            r.setdefault("agents", 20)
            w.writerow({**r, "seed": 1 + i % 5, "maxTicks": 5000})
    return path


def test_the_claims_script_judges_a_sweep_csv(tmp_path: Path, capsys) -> None:
    claims = _bench("thesis_claims")
    out = tmp_path / "c.json"
    assert claims.main([str(_rows(tmp_path)), "--json", str(out)]) == 0
    table = capsys.readouterr().out
    data = json.loads(out.read_text())
    got = {c["claim"].split(":")[0]: c["verdict"] for c in data["claims"]}
    assert got["Graph 1a"] == "depends on the time unit"
    assert got["Graph 1b"] == "depends on the time unit"      # it rises in moves, steadily
    assert got["Graph 2"] == got["Graph 3"] == got["Graph 4"] == "holds"
    assert got["rPower 1.25 (ant) took unreasonably long to converge"] == "does not hold"
    assert got["firefly robots converge quicker than ant robots (Graphs 1-4)"] == "holds"
    assert got["more robots converge quicker (scalability)"] == "holds"
    assert got["Figures 22-24"] == "holds"
    fd0 = next(c for c in data["claims"] if c["source"] == "3.9.2")
    assert fd0["verdict"] == "holds" and "firefly: 2 of 5 stalled" in fd0["figure"]
    assert data["meta"]["runs"][0]["seeds"] == 5
    assert table.startswith("Made by `touchswarm sweep --thesis --scenario netlogo")
    assert claims.render(data) in table
    # and it renders the same table again from its JSON
    assert claims.main(["--from-json", str(out)]) == 0
    assert claims.render(data) in capsys.readouterr().out


@pytest.mark.parametrize("argv, words", [([], "give sweep.csv files or --from-json FILE"),
                                         (["/nonexistent.csv"], "no such file")])
def test_the_claims_script_refuses_bad_input_in_one_line(argv, words, capsys) -> None:
    assert _bench("thesis_claims").main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err


def test_a_sweep_without_the_polygon_column_is_named(tmp_path: Path, capsys) -> None:
    path = tmp_path / "old.csv"
    path.write_text("experiment,converged_tick,converged_moves,shape_iou\ngraph1,1,1,0.5\n")
    assert _bench("thesis_claims").main([str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no polygon_iou" in err


def test_the_options_script_runs_and_prints_the_docs_tables_rows(capsys) -> None:
    opts = _bench("thesis_options")
    assert opts.main(["--seeds", "1", "--engine", "reference", "--max-ticks", "40",
                      "--workers", "0", "--markdown"]) == 0
    out = capsys.readouterr().out
    tiny = _table(out[out.index("| option |"):])
    docs = _table(_block("thesis_options"))
    assert tiny[0] == docs[0]
    assert [r[:3] for r in tiny] == [r[:3] for r in docs]
    assert all(len(r) == len(docs[0]) for r in docs + tiny)
    assert all(c.endswith("(1/1)") for r in tiny[1:] for c in r[3:])


def test_the_appendix_script_runs_and_prints_the_docs_tables_rows(capsys) -> None:
    app = _bench("appendix_a")
    assert app.main(["--seeds", "2", "--engine", "reference", "--max-ticks", "40",
                     "--markdown"]) == 0
    out = capsys.readouterr().out
    tiny = _table(out[out.index("| model |"):])
    docs = _table(_block("appendix_a"))
    assert tiny[0] == docs[0]
    assert [r[:2] for r in tiny] == [r[:2] for r in docs]
    assert all(len(r) == len(docs[0]) for r in docs + tiny)
    assert app.binomial_range(18, 50) == (12, 25)
    # the 200-seed run at fieldDefiance 0 has the same columns, its rows those points
    more = _table(_block("appendix_a", " --seeds 200 --defiance 0"))
    assert more[0] == tiny[0] and [r[:2] for r in more[1:]] == [["firefly", "0"], ["ant", "0"]]
    assert all(len(r) == len(more[0]) for r in more)
    assert round(app.fisher_exact(17, 50, 10, 50), 3) == 0.176


def test_the_smaller_tables_are_what_the_script_renders_from_their_statistics() -> None:
    tables = _bench("thesis_tables")
    data = json.loads((ROOT / "bench" / "thesis_tables.json").read_text())
    for t, path in tables.TABLES.items():
        text = (ROOT / path).read_text()
        assert tables.put(text, data, path) == text
        begin, end = tables.markers(t)
        assert text.split(begin, 1)[1].split(end, 1)[0].strip() == tables.render(data, t)
    # every run the tables read, with the command that made it
    assert set(data["meta"]["runs"]) == set(tables.RUNS)
    for name, meta in data["meta"]["runs"].items():
        assert meta["command"] == tables.RUNS[name][0]


def test_the_tables_script_reduces_a_sweep_csv(tmp_path: Path, capsys) -> None:
    tables = _bench("thesis_tables")
    path = tmp_path / "sweep.csv"
    rows = [{"movementModel": "ant", "robotVisionSpan": "45.0", "seed": s,
             "converged_tick": "" if s == 3 else 10 * s, "converged_moves": "" if s == 3 else 10 * s,
             "delivered": "True" if s == 1 else "False", "home_tick": 30 if s == 1 else "",
             "found_tick": s}
            for s in (1, 2, 3)]
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    out = tmp_path / "t.json"
    assert tables.main([f"Sens-span={path}", "--json", str(out)]) == 2     # a table lacks points
    assert "no such point" in capsys.readouterr().err
    data = json.loads(out.read_text())
    p = data["points"][0]
    assert (p["robotVisionSpan"], p["n"], p["stalled"], p["delivered"]) == ("45", 3, 1, 1)
    assert (p["it_median"], p["transport_median"], p["found_median"]) == (15.0, 20.0, 2.0)
    assert (p["it_min"], p["it_max"], p["home_min"], p["home_max"]) == (10.0, 20.0, 30.0, 30.0)
    assert p["it_sd"] == 7.1 and p["iou_mean"] is None
    # --update replaces the runs given and keeps the others
    data["meta"]["runs"]["Models"] = {"command": tables.RUNS["Models"][0]}
    data["points"].append({"run": "Models", "movementModel": "frog"})
    data["points"][0]["n"] = 99
    out.write_text(json.dumps(data))
    assert tables.main([f"Sens-span={path}", "--json", str(out), "--update"]) == 2
    capsys.readouterr()
    again = json.loads(out.read_text())
    assert set(again["meta"]["runs"]) == {"Sens-span", "Models"}
    assert [q["run"] for q in again["points"]] == ["Models", "Sens-span"]
    assert again["points"][1]["n"] == 3          # the stale Sens-span point replaced
    assert tables.main([f"Sens-span={path}", "--update"]) == 2
    assert "--update needs --json" in capsys.readouterr().err
    assert tables.main(["nonsense=" + str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "must be one of" in err


def test_the_extension_docs_seed_runs_are_what_they_say() -> None:
    """The single-seed delivery ticks the extension docs quote (reference
    engine, a few hundred ticks each), and the crate's cells and weight."""
    from sim_backend.engine import Engine
    from sim_backend.scenario import load

    def home(name: str, seed: int, **over) -> int:
        sc = load(name)
        return Engine(sc.replace(**over) if over else sc, seed).run().summary()["home_tick"]

    moth = (home("default", 1, movementModel="moth"), home("default", 2, movementModel="moth"))
    quoted = f"seeds 1 and 2 at ticks {moth[0]} and {moth[1]}"
    for doc in ("movement-models.md", "extensions.md"):
        assert quoted in " ".join((ROOT / "docs" / doc).read_text().split()), doc
    scen = " ".join((ROOT / "docs" / "scenarios.md").read_text().split())
    assert (f"Seed 1 of each: `crate` delivered at tick {home('crate', 1)}, `decoy` "
            f"{home('decoy', 1)}, `wall` {home('wall', 1)}") in scen
    crate = load("crate")
    assert f"{len(crate.objects[0].cells)} cells: weight {crate.objectWeight:g}" in scen


def test_the_size_table_has_every_point_of_the_preset() -> None:
    """Both size runs hold the preset's points, so a changed preset cannot
    leave the swarm-size table of docs/extensions.md on the old ones."""
    from sim_backend.arena_presets import SEEDS, size_points
    tables = _bench("thesis_tables")
    data = json.loads((ROOT / "bench" / "thesis_tables.json").read_text())
    want = [dict(p.params) for p in size_points()]
    for run in tables.SIZE_RUNS:
        got = [p for p in data["points"] if p["run"] == run]
        assert [int(p["agents"]) for p in got] == [w["agents"] for w in want], run
        assert all(p["n"] == SEEDS for p in got), run
        assert {int(p["worldSize"]) for p in got if int(p["agents"]) > 300} == \
            {w["worldSize"] for w in want if "worldSize" in w}, run


def test_the_field_table_has_every_point_of_the_preset() -> None:
    """The field run holds the preset's points, so a changed preset cannot
    leave the field table of docs/extensions.md on the old ones."""
    from sim_backend.arena_presets import SEEDS, field_points
    tables = _bench("thesis_tables")
    data = json.loads((ROOT / "bench" / "thesis_tables.json").read_text())
    want = [{k: str(v) for k, v in p.params} for p in field_points()]
    for run in tables.FIELD_RUNS:
        got = [p for p in data["points"] if p["run"] == run]
        assert [{k: p[k] for k in ("agents", "field", "crowd")} for p in got] == want, run
        assert all(p["n"] == SEEDS for p in got), run


def test_the_obstacles_table_has_every_point_of_the_preset() -> None:
    """The obstacles run holds the preset's points (wall on, then off), so a
    changed wall or preset cannot leave the obstacles table of
    docs/extensions.md on the old ones."""
    from sim_backend.arena_presets import SEEDS, obstacle_points
    from sim_backend.sweep import _point_text
    tables = _bench("thesis_tables")
    data = json.loads((ROOT / "bench" / "thesis_tables.json").read_text())
    want = [_point_text(p) for p in obstacle_points()]
    for run in tables.OBSTACLE_RUNS:
        got = [p for p in data["points"] if p["run"] == run]
        assert [p["point"] for p in got] == want, run
        assert all(p["n"] == SEEDS for p in got), run
        assert data["meta"]["runs"][run]["seeds"] == SEEDS, run
