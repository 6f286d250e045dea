"""The world's sweep presets (`touchswarm sweep --preset sizes|obstacles|field`)."""

import pytest

from sim_backend import arena_presets
from sim_backend.scenario import load, validate
from sim_backend.sweep import validate_points


@pytest.mark.parametrize("name", sorted(arena_presets.PRESETS))
def test_every_preset_point_is_a_valid_scenario(name):
    base, make = arena_presets.PRESETS[name]
    validate_points(make(), load(base), {"maxTicks": arena_presets.MAX_TICKS})


def test_large_swarms_get_arenas_of_the_default_density():
    sizes = {dict(p.params)["agents"]: dict(p.params).get("worldSize", 18)
             for p in arena_presets.size_points()}
    assert sorted(sizes) == [20, 50, 100, 200, 300, 1000, 10000]
    assert sizes[1000] == 131 and sizes[10000] == 414
    for a in (1000, 10000):
        density = a / (2 * sizes[a] + 1) ** 2
        assert abs(density / arena_presets.DENSITY - 1) < 0.02
    assert validate({"agents": 10000, "worldSize": 414}).worldSize == 414


def test_summary_and_figure_from_sweep_csv_rows(tmp_path):
    rows = [{"point": "agents=20", "delivered": "True", "home_tick": "100", "shape_iou": "0.5"},
            {"point": "agents=20", "delivered": "False", "home_tick": "None",
             "shape_iou": "0.25"},
            {"point": "obstacles=()", "delivered": "True", "home_tick": "40",
             "shape_iou": "1.0"}]
    s = arena_presets.summarise(rows)
    assert s == [{"point": "agents=20", "n": 2, "delivered": 1, "median_home_tick": 100.0,
                  "mean_iou": 0.375},
                 {"point": "obstacles=off", "n": 1, "delivered": 1, "median_home_tick": 40.0,
                  "mean_iou": 1.0}]
    assert "| agents=20 | 1/2 | 100.0 | 0.375 |" in arena_presets.table(rows)
    (png,) = arena_presets.plots(rows, tmp_path, "sizes")
    assert png.name == "sizes.png" and png.stat().st_size > 1000


def test_the_cli_preset_runs_its_grid_and_draws_its_figure(tmp_path):
    from bridge.cli import main
    from sim_backend.sweep import read_csv
    assert main(["sweep", "--preset", "obstacles", "--seeds", "1", "--executor", "inline",
                 "--out", str(tmp_path)]) == 0
    rows = read_csv(tmp_path / "sweep.csv")
    assert len(rows) == 2 and {r["experiment"] for r in rows} == {"obstacles"}
    # with the wall, then without
    assert [r["point"] == "obstacles=()" for r in rows] == [False, True]
    assert rows[0]["pieces"] == rows[1]["pieces"] + " wall@[-12, 0]:18cells"
    assert (tmp_path / "obstacles.png").exists()


def test_a_preset_with_a_grid_is_refused(capsys):
    from bridge.cli import main
    assert main(["sweep", "--preset", "sizes", "--grid", "agents=1,2"]) == 2
    assert "--preset sizes runs its own grid" in capsys.readouterr().err
