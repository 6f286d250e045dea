"""Invariants of the world's state that sim_backend/kernel.py relies on,
checked at every tick of whole runs in the reference engine (the batch
engine is held equal to it by tests/harness.py).

Holder and cell agree: a robot's `held` cell is owned by that robot's node,
and an owned cell is its owner's `held` cell. kernel._carrier finds the
carried object's holders from its cells through this, instead of walking
every robot.
"""

import pytest

from sim_backend.engine import Engine
from sim_backend.scenario import load, validate

RUNS = [
    ({"agents": 150, "maxTicks": 1200}, 1),                                  # crowd yield
    ({"agents": 150, "crowd": "block", "maxTicks": 400}, 2),
    ({"agents": 300, "maxTicks": 400, "movementModel": "ant"}, 6),          # pushes along
    ({"agents": 120, "maxTicks": 800, "deathRate": 0.3, "deadlockRate": 0.2,
      "ignoreHostRate": 0.1, "randomRate": 0.1}, 3),                        # holders die
    ({"agents": 120, "maxTicks": 1500, "wrap": True}, 4),
    ({"agents": 120, "maxTicks": 1500, "activation": "netlogo"}, 7),
    ({"agents": 120, "maxTicks": 1500, "field": "dynamic"}, 8),
    ({"agents": 120, "maxTicks": 1500, "breeds": [
        {"count": 60, "movementModel": "levy"}, {"count": 60, "movementModel": "ant"}]}, 9),
]


def holders_agree(w) -> list[str]:
    bad = []
    for i, k in enumerate(w.held):
        if k >= 0 and w.owner[k] != i + 1:
            bad.append(f"robot {i + 1} holds cell {k}, owned by {w.owner[k]}")
    for k, node in enumerate(w.owner):
        if node > 0 and w.held[node - 1] != k:
            bad.append(f"cell {k} is owned by {node}, which holds {w.held[node - 1]}")
    return bad


def run_checked(sc, seed):
    e = Engine(sc, seed)
    held_ticks = 0
    while not e.coordinator.done() and e.tick < sc.maxTicks:
        e.step()
        assert holders_agree(e.world) == [], (sc.name, seed, "tick", e.tick)
        held_ticks += any(k >= 0 for k in e.world.held)
    return e, held_ticks


@pytest.mark.parametrize("raw,seed", RUNS, ids=lambda v: ",".join(
    f"{k}={x}" for k, x in v.items() if k != "maxTicks") if isinstance(v, dict) else str(v))
def test_a_holders_cell_is_owned_by_it_at_every_tick(raw, seed):
    e, held_ticks = run_checked(validate(raw), seed)
    assert held_ticks > 0, "nothing was ever held: a weak check"


@pytest.mark.parametrize("name", ["wall", "decoy"])
def test_holders_agree_with_obstacles_and_a_decoy(name):
    e, held_ticks = run_checked(load(name).replace(agents=120), 1)
    assert held_ticks > 0


def test_the_check_sees_a_broken_state():
    e = Engine(validate({"agents": 10}), 1)
    w = e.world
    k = w.owner.index(0)
    w.owner[k] = 3                      # a cell owned by a robot that holds nothing
    assert holders_agree(w) == [f"cell {k} is owned by 3, which holds -1"]


def test_the_step_tables_are_the_fixed_point_steps():
    """kernel.AHEAD_DX/AHEAD_DY and degrees stand in for fx.dx/fx.dy on every
    heading, in range or not (a heading is reduced only when out of 0..359)."""
    from firmware_logic import fixedpoint as fx
    from sim_backend import kernel

    for h in range(-1080, 1081):
        assert kernel.degrees(h) == h % 360
        for step in (fx.ONE, fx.QUARTER, 100):
            assert kernel.step_dx(h, step) == fx.dx(h, step)
            assert kernel.step_dy(h, step) == fx.dy(h, step)
        assert kernel.ahead_x(1000, h) == fx.patch(1000 + fx.dx(h, fx.ONE))
        assert kernel.ahead_y(-1000, h) == fx.patch(-1000 + fx.dy(h, fx.ONE))
