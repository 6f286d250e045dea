"""The firmware on MicroPython: compiles with mpy-cross, loads in the unix
port, runs the seeded scripted robot to the same trace as CPython for both
movement models, visits every FSM state and allocates nothing per step.

mpy-cross and micropython are dev dependencies (`make test` installs them),
so nothing here is skipped.
"""

from __future__ import annotations

import argparse
import json
import shutil
import stat
from pathlib import Path

import pytest

from bridge.firmware import cli
from bridge.firmware.conformance import (
    Report, RunParams, Tools, find_tools, first_divergence, run_conformance)
from firmware_logic.behaviours.thesis.spec import ANT, FIREFLY
from firmware_logic.behaviours.thesis.spec import STATES as STATE_NAMES
from bridge.firmware.subset_check import firmware_files, package_dir
from sim_backend import registry


@pytest.fixture(scope="module")
def report() -> Report:
    return run_conformance()


def firmware_copy(tmp_path: Path) -> Path:
    dst = tmp_path / "firmware_logic"
    shutil.copytree(package_dir(), dst, ignore=shutil.ignore_patterns("__pycache__"))
    return dst


def edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert text.count(old) == 1, old
    path.write_text(text.replace(old, new))


def test_tools_agree_and_every_module_compiles(report: Report) -> None:
    assert report.errors == []
    assert report.mpy_version_cross.split(".")[0] == report.mpy_version_port.split(".")[0]
    assert report.loaded_from == "mpy"
    # the firmware core as firmware_logic/, the behaviour as the package behaviour/
    root = package_dir()
    core = {p.relative_to(root).with_suffix("").as_posix()
            for p in firmware_files(root) if "behaviours" not in p.relative_to(root).parts}
    thesis = registry.load("thesis").folder
    own = {"behaviour." + p.stem for p in firmware_files(thesis)}
    assert {"board", "scripted", "messages"} <= core and "behaviour.robot" in own
    assert set(report.mpy_sizes) == core | own
    assert all(size > 0 for size in report.mpy_sizes.values())
    assert report.mpy_total == sum(report.mpy_sizes.values())


@pytest.mark.parametrize("index,model", [(0, "firefly"), (1, "ant")])
def test_traces_identical_and_cover_the_fsm(report: Report, index: int, model: str) -> None:
    m = report.models[index]
    assert m.model == model
    assert m.identical, str(m.divergence)
    assert m.divergence is None
    assert m.trace_lines > 5000 and m.actions > 1000
    assert m.states_visited == list(STATE_NAMES)
    assert m.max_abs_value < 1 << 30        # small ints on a 32-bit board too


@pytest.mark.parametrize("index", [0, 1])
def test_no_heap_allocation_per_step(report: Report, index: int) -> None:
    m = report.models[index]
    assert m.heap_steps == 2000
    assert m.heap_bytes == 0
    assert m.heap_per_step == 0
    assert m.heap_locked_ok, m.heap_locked_failed_step
    assert m.heap_states == list(STATE_NAMES)   # every state's code was measured


def test_report_ok_and_json_ready(report: Report) -> None:
    assert report.ok
    d = json.loads(json.dumps(report.as_dict()))
    assert d["ok"] is True and d["mpy_total"] == report.mpy_total


def test_divergent_firmware_is_detected(tmp_path: Path) -> None:
    fw = firmware_copy(tmp_path)
    edit(fw / "behaviours" / "thesis" / "robot.py", "RETX_FIRST = 4\n", "RETX_FIRST = 5\n")
    rep = run_conformance(fw, RunParams(ticks=300), models=(FIREFLY,), heap_steps=50)
    m = rep.models[0]
    assert not m.identical and not rep.ok
    d = m.divergence
    assert d is not None and d.line > 1
    assert d.cpython != d.micropython
    assert "line %d" % d.line in str(d)


def test_allocating_firmware_is_measured(tmp_path: Path) -> None:
    fw = firmware_copy(tmp_path)
    edit(fw / "behaviours" / "thesis" / "robot.py", "        self.ticks += 1\n",
         "        self.ticks += 1\n        self.last = (self.ticks, self.state)\n")
    rep = run_conformance(fw, RunParams(ticks=300), models=(ANT,), heap_steps=300)
    m = rep.models[0]
    assert m.identical                     # same behaviour ...
    assert m.heap_bytes >= 300 * 16        # ... but a tuple per step
    assert not m.heap_locked_ok and m.heap_locked_failed_step == 0
    assert not rep.ok


def _script(path: Path, body: str) -> Path:
    path.write_text("#!/bin/sh\n" + body)
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return path


def test_mpy_version_mismatch_is_reported(tmp_path: Path) -> None:
    real = find_tools()
    # an mpy-cross that claims an older format and writes .mpy v5 headers
    fake = _script(tmp_path / "mpy-cross", f"""
if [ "$1" = "--version" ]; then echo "MicroPython v1.12; mpy-cross emitting mpy v5"; exit 0; fi
"{real.mpy_cross}" "$@" || exit $?
printf '\\005' | dd of="$2" bs=1 seek=1 conv=notrunc 2>/dev/null
""")
    rep = run_conformance(None, RunParams(ticks=50), models=(FIREFLY,),
                          heap_steps=10, tools=Tools(fake, real.micropython))
    assert rep.mpy_version_cross == "5.0"
    assert any("mpy-cross emits .mpy v5.0" in e for e in rep.errors), rep.errors
    assert any("could not load the .mpy files" in e and "incompatible" in e
               for e in rep.errors), rep.errors
    assert rep.loaded_from == "py"         # the traces fell back to the sources
    assert rep.models[0].identical
    assert not rep.ok


def test_first_divergence() -> None:
    assert first_divergence(["a", "b"], ["a", "b"]) is None
    d = first_divergence(["a", "b"], ["a", "c"])
    assert d is not None and (d.line, d.cpython, d.micropython) == (2, "b", "c")
    d = first_divergence(["a"], ["a", "x"])
    assert d is not None and (d.line, d.cpython, d.micropython) == (2, None, "x")


def test_cli_check_json(capsys: pytest.CaptureFixture[str]) -> None:
    args = argparse.Namespace(json=True, seed=12345, node=3, ticks=2000)
    rc = cli.cmd_check(args)
    out = json.loads(capsys.readouterr().out)
    assert out["conformance_ok"] is True
    assert out["ok"] == (not out["subset_violations"] and out["conformance_ok"])
    assert rc == (0 if out["ok"] else 1)
    assert out["mpy_total"] > 0
    from firmware_logic.behaviours.thesis import spec
    assert [m["model"] for m in out["models"]] == [n for _, n in spec.MODELS]
    assert all(m["heap_per_step"] == 0 for m in out["models"])


def test_cli_check_text(capsys: pytest.CaptureFixture[str]) -> None:
    rc = cli.main(["check", "--ticks", "2000"])
    text = capsys.readouterr().out
    assert "firefly: traces identical (" in text and "ant: traces identical (" in text
    assert "total" in text and "bytes/step" in text
    assert text.rstrip().endswith("PASS" if rc == 0 else "FAIL")


def test_script_hal_implements_every_hal_method() -> None:
    from firmware_logic.hal import Hal
    from firmware_logic.scripted import ScriptHal

    methods = [n for n, v in vars(Hal).items() if callable(v) and not n.startswith("_")]
    assert len(methods) == 13
    for name in methods:
        assert name in vars(ScriptHal), name


def test_script_hal_trace_buffer_is_bounded() -> None:
    from firmware_logic.behaviours.thesis.robot import Robot
    from firmware_logic.scripted import ScriptHal

    robot = Robot(3, 12345, FIREFLY, 45, 2, 100)
    hal = ScriptHal(12345, 100, 64)
    for _ in range(100):
        robot.step(hal)
    assert len(hal.buf) == 64 and hal.n <= 64
    assert hal.dropped > 0 and hal.records > hal.dropped
    lines = hal.drain_lines()
    assert lines and hal.n == 0
    assert lines[0] == "1 recv -> 0"
