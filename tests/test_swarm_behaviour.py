"""`touchswarm robots` (bridge/host/swarm.py) knows the swarm ended from the
behaviour's own "halt" state (spec.STATES), not the thesis's constant."""

from __future__ import annotations

from pathlib import Path

import pytest

from bridge.cli import main
from bridge.host.swarm import all_halted, swarm_engine, swarm_summary
from bridge.host.transport import CanTransport
from bridge.links import open_bus
from bridge.links.canlink import private_channel
from firmware_logic import messages as msg
from sim_backend import registry
from sim_backend import scenario


@pytest.mark.parametrize("name", ["thesis", "aggregate"])
def test_swarm_ends_on_the_behaviours_halt_state(name: str) -> None:
    b = registry.load(name)
    assert b.halt_state == b.spec.STATES.index("halt")
    sc = scenario.load("default").replace(agents=4, objectWeight=2, behaviour=name)
    url = f"virtual://{private_channel('swarm')}"
    with open_bus(url) as rb, CanTransport(open_bus(url)) as host:
        engine = swarm_engine(sc, 1, rb)
        for _ in range(3):
            engine.step()
        assert not engine.finished() and not swarm_summary(engine)["halted"]
        host.send(msg.HOST, msg.HALT, (0,))        # the host's HALT, broadcast
        for _ in range(3):
            engine.step()
        assert all_halted(engine) and engine.finished()
        s = swarm_summary(engine)
    assert s["halted"] and s["states"] == ["halt"] * 4 and s["behaviour"] == name


def test_a_behaviour_without_a_halt_state_is_refused(tmp_path: Path) -> None:
    src = registry.load("aggregate").folder
    dst = tmp_path / "nohalt"
    dst.mkdir()
    for p in src.glob("*.py"):
        text = p.read_text().replace("behaviours.aggregate", "behaviours.nohalt")
        if p.name == "spec.py":
            text = text.replace('"stay", "halt")', '"stay", "stop")')
        (dst / p.name).write_text(text)
    with pytest.raises(registry.BehaviourError, match='has no "halt" state'):
        registry.load(dst)


def test_behaviour_option_is_the_scenario_key(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["run", "--behaviour", "nosuch"]) == 2
    err = capsys.readouterr().err.strip()
    assert "not an installed behaviour" in err and "\n" not in err
    assert main(["run", "--behaviour", "aggregate", "--set", "behaviour=thesis"]) == 2
    assert "disagree" in capsys.readouterr().err

