"""A behaviour in a folder outside the repository, made by the scaffold and
edited there, passes `firmware check` with its own relative imports, its own
parameters and its own down messages; a constructor that does not fit its
robot_args is refused in one line.

The deploy of such a folder to MicroPython (the unix port behind a pty) is in
hil_tests/test_micropython_robot.py.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from bridge.cli import main
from sim_backend import registry
from sim_backend import scenario


@pytest.fixture(autouse=True)
def own_schema():
    """The behaviours here put their message kinds in this process's schema
    (messages.activate); leave it as it was for the tests after them."""
    from firmware_logic import messages as msg
    active, schema = list(msg.ACTIVE), dict(msg.SCHEMA)
    yield
    msg.ACTIVE[:] = active
    msg.SCHEMA.clear()
    msg.SCHEMA.update(schema)


def scaffold(parent: Path, name: str) -> Path:
    assert main(["behaviour", "new", name, "--into", str(parent)]) == 0
    return parent / name


def edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert text.count(old) == 1, (path, old)
    path.write_text(text.replace(old, new))


def with_down_only_state(folder: Path, nudge_direction: str = "DOWN", kind: int = 9) -> None:
    """Give the scaffold a state `flee` that only the host's own down message
    NUDGE leads to: a stopped robot told NUDGE walks away for 5 ticks.
    The robot reads its own module `moves` by relative import."""
    spec, robot = folder / "spec.py", folder / "robot.py"
    edit(spec, "from firmware_logic.messages import UP\n",
         "from firmware_logic.messages import DOWN, UP\n")
    edit(spec, 'STATES = ("search", "climb", "stay", "halt")',
         'FLEE = 4     # told NUDGE while stopped: walks away\n'
         'STATES = ("search", "climb", "stay", "halt", "flee")')
    edit(spec, "MESSAGES = (\n",
         f"NUDGE = {kind}    # host -> robot: leave your stop\n"
         "MESSAGES = (\n"
         f'    (NUDGE, "NUDGE", {nudge_direction}, "host -> robot: leave your stop",\n'
         '     (("seq", 1, 0, 1, "", None, None, ""),)),\n')
    (folder / "moves.py").write_text('"""How far a nudged robot flees."""\n\nFLEE_TICKS = 5\n')
    edit(robot, "from .spec import CLIMB, HALT, LEAVE, SEARCH, STAY, WALK\n",
         "from .spec import CLIMB, FLEE, HALT, LEAVE, NUDGE, SEARCH, STAY, WALK\n"
         "from . import moves\n")
    edit(robot, "        self.rxbuf = [0, 0, 0, 0, 0, 0]\n",
         "        self.rxbuf = [0, 0, 0, 0, 0, 0]\n        self.flee = 0\n")
    edit(robot, "            elif k == msg.HALT and self.state != HALT:\n",
         "            elif k == NUDGE and self.state == STAY:\n"
         "                self.state = FLEE\n"
         "                self.flee = moves.FLEE_TICKS\n"
         "                hal.beacon(0)\n"
         "            elif k == msg.HALT and self.state != HALT:\n")
    edit(robot, "        if s == SEARCH or s == CLIMB:\n            self._move(hal)\n",
         "        if s == SEARCH or s == CLIMB:\n            self._move(hal)\n"
         "        elif s == FLEE:\n"
         "            self._wander(hal)\n"
         "            self.flee -= 1\n"
         "            if self.flee <= 0:\n"
         "                self.state = SEARCH\n")


def with_parameter_and_measure(folder: Path) -> None:
    """fleeTicks, the behaviour's own parameter, reaches the robot through
    robot_args (a seventh constructor argument); the host NUDGEs every third
    stop it accepts and counts them in its own measure `nudges`."""
    spec, robot, coord, init = (folder / f for f in ("spec.py", "robot.py", "coordinator.py",
                                                     "__init__.py"))
    edit(spec, '    ("quorum", 80, 1, 100, "percent of the swarm that must have stopped"),\n',
         '    ("quorum", 80, 1, 100, "percent of the swarm that must have stopped"),\n'
         '    ("fleeTicks", 5, 1, 50, "ticks a nudged robot walks away"),\n')
    edit(spec, '    ("largest", "robots in the largest cluster"),\n)\n\n# values',
         '    ("largest", "robots in the largest cluster"),\n'
         '    ("nudges", "NUDGE commands the host sent"),\n)\n\n# values')
    edit(init, "    return (node, seed, model, sc.robotVisionSpan, sc.fieldDefiance, 100)",
         "    return (node, seed, model, sc.robotVisionSpan, sc.fieldDefiance, 100, sc.fleeTicks)")
    edit(robot, "    def __init__(self, node, seed, model, vision_span, field_defiance, power):\n",
         "    def __init__(self, node, seed, model, vision_span, field_defiance, power,\n"
         "                 flee_ticks):\n        self.flee_ticks = flee_ticks\n")
    edit(robot, "                self.flee = moves.FLEE_TICKS\n",
         "                self.flee = self.flee_ticks\n")
    edit(coord, "from .spec import LEAVE, MODELS, STAY\n", "from .spec import LEAVE, MODELS, NUDGE, STAY\n")
    edit(coord, "        self.outbox = []\n\n    def on_message",
         "        self.outbox = []\n        self.nudges = 0\n\n    def on_message")
    edit(coord, "                if self.found_tick < 0:\n",
         "                if len(self.touches) % 3 == 0:\n"
         "                    self.nudges += 1\n"
         "                    self.outbox.append((node, NUDGE, (f[0],)))\n"
         "                if self.found_tick < 0:\n")
    edit(coord, '                "largest": sizes[0] if sizes else 0}',
         '                "largest": sizes[0] if sizes else 0, "nudges": self.nudges}')


def spread_behaviour(tmp_path: Path) -> Path:
    """A third behaviour: aggregate's scaffold as "spread",
    outside the repository, with a state only its own NUDGE leads to, its own
    parameter and its own measure. The same source each time, so its soa
    step compiles once per machine (tests/test_batch_engine.py runs it too)."""
    parent = tmp_path / "elsewhere"
    parent.mkdir()
    folder = scaffold(parent, "spread")
    with_down_only_state(folder)
    with_parameter_and_measure(folder)
    return folder


def test_a_scaffold_outside_the_repo_passes_firmware_check_with_its_own_parameters(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = scaffold(tmp_path, "spread")
    assert "from .spec import" in (folder / "robot.py").read_text()   # the relative style
    assert not str(folder.resolve()).startswith(str(Path(registry.__file__).parents[1]))
    rc = main(["firmware", "check", "--behaviour", str(folder), "--set", "robotVisionSpan=30",
               "--ticks", "1500"])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "subset check: 0 violations" in out
    assert "behaviour.robot" in out                     # compiled as the board's package
    # the behaviour's own parameter reached the robot's arguments, per model
    assert "robot: Robot(3, 12345, 1, 30, 2, 100)" in out
    assert "robot: Robot(3, 12345, 2, 30, 2, 100)" in out
    assert out.count("traces identical") == 2 and out.rstrip().endswith("firmware check: PASS")
    # a value outside the parameter's range is refused in one line
    assert main(["firmware", "check", "--behaviour", str(folder), "--set",
                 "robotVisionSpan=999"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "robotVisionSpan" in err and "0..360" in err


def test_a_state_reached_only_by_a_down_message_runs_on_micropython(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = scaffold(tmp_path, "nudged")
    with_down_only_state(folder)
    rc = main(["firmware", "check", "--behaviour", str(folder), "--ticks", "1500"])
    out = capsys.readouterr().out
    assert rc == 0, out
    assert "down messages the script sent: NUDGE" in out
    visited = re.findall(r"states visited: (.*)", out)
    assert visited == ["search climb stay halt flee"] * 2, visited
    assert "FAIL" not in out


def test_a_state_never_reached_is_named_in_a_fail_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    # NUDGE declared as a robot's message: the host never sends it, so
    # nothing leads to flee (another kind: the schema of one process holds
    # the down NUDGE of the test above)
    folder = scaffold(tmp_path, "unnudged")
    with_down_only_state(folder, nudge_direction="UP", kind=12)
    rc = main(["firmware", "check", "--behaviour", str(folder), "--ticks", "1500"])
    out = capsys.readouterr().out
    assert rc == 1
    assert "down messages the script sent" not in out
    assert "FAIL: state 'flee' was never reached under MicroPython (firefly, ant)" in out
    assert out.count("FAIL: state") == 1
    assert out.rstrip().endswith("firmware check: FAIL")
    assert main(["firmware", "check", "--behaviour", str(folder), "--ticks", "1500",
                 "--json"]) == 1
    d = json.loads(capsys.readouterr().out)
    assert d["unvisited"] == {"flee": ["firefly", "ant"]} and d["ok"] is False


def test_a_constructor_that_does_not_fit_robot_args_is_one_line(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = scaffold(tmp_path, "seven")
    edit(folder / "robot.py",
         "    def __init__(self, node, seed, model, vision_span, field_defiance, power):\n",
         "    def __init__(self, node, seed, model, vision_span, field_defiance, power, shy):\n")
    b = registry.load(folder)
    assert b.arity == (7, 7)
    with pytest.raises(registry.BehaviourError) as err:
        b.robot_args(1, 1, scenario.validate({"behaviour": str(folder)}))
    line = str(err.value)
    assert "\n" not in line
    assert line == (f"behaviour 'seven': robot_args in {folder.resolve()}/__init__.py gives 6 "
                    f"arguments, but Robot.__init__ in {folder.resolve()}/robot.py takes 7; "
                    "make them agree")
    for argv in (["firmware", "check", "--behaviour", str(folder)],
                 ["run", "--behaviour", str(folder), "--set", "maxTicks=10"]):
        assert main(argv) == 2
        err_text = capsys.readouterr().err
        assert err_text == f"touchswarm: error: {line}\n", argv
    # behaviour check's first step says it too
    assert main(["behaviour", "check", str(folder), "--only", "load"]) == 1
    out = capsys.readouterr().out
    assert re.search(r"load +FAIL .* " + re.escape(line), out), out


def test_optional_constructor_arguments_fit() -> None:
    thesis = registry.load("thesis")
    lo, hi = thesis.arity
    assert lo == 6 and hi == 13          # six required, seven with defaults
    args = thesis.robot_args(1, 1, scenario.validate({"behaviour": "thesis"}))
    assert lo <= len(args) <= hi
