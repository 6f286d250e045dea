"""`object = "none"`: whether the world has an object is the
scenario's choice. A behaviour that carries nothing runs in an empty arena,
the same in both engines; one that carries an object by its weight is
refused in one line."""

from __future__ import annotations

import pytest

from bridge.cli import main
from sim_backend.batch.soa import run_batch_results
from sim_backend.engine import run
from sim_backend.errors import ScenarioError
from sim_backend.scenario import validate

EMPTY = {"behaviour": "aggregate", "object": "none", "homeX": 0, "homeY": 0}


def test_an_empty_arena_has_no_object_and_runs_alike_in_both_engines() -> None:
    sc = validate({**EMPTY, "agents": 30, "worldSize": 10})
    assert sc.pieces() == []
    ref = [run(sc, seed) for seed in (1, 2)]
    assert all(r.world.object_cells == [] for r in ref)
    assert all(cell == 0 for cell in ref[0].world.obj)          # nothing placed
    soa = run_batch_results(sc, [1, 2])
    for a, b in zip(ref, soa):
        assert a.summary() == b.summary()
    assert ref[0].summary()["delivered"]                       # the quorum stopped


def test_an_empty_arena_takes_more_robots_than_the_bar_allows() -> None:
    with pytest.raises(ScenarioError, match="object: 'bar'.*does not fit the arena"):
        validate({"behaviour": "aggregate", "agents": 60, "worldSize": 10})
    assert validate({**EMPTY, "agents": 60, "worldSize": 10}).agents == 60


def test_a_behaviour_that_carries_is_refused_an_empty_arena(capsys) -> None:
    with pytest.raises(ScenarioError) as err:
        validate({"object": "none"})
    assert str(err.value) == ("object: behaviour 'thesis' carries an object by its weight; "
                              "'none' leaves it none: name a shape")
    assert main(["run", "--set", "object=nothing"]) == 2
    assert "object: expected 1-4, 'none' or one of" in capsys.readouterr().err


def test_obstacles_without_an_object() -> None:
    sc = validate({**EMPTY, "obstacles": [{"shape": "square", "at": [5, 5]}]})
    r = run(sc, 1)
    assert r.world.object_cells == [] and len(r.world.obstacle_cells) == 16
