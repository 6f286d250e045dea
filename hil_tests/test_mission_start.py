"""`touchswarm deploy --start`, then a mission with the board as `mpy://PORT`,
on MicroPython's unix port behind a pty, as a user runs the two.

What the host reads besides the board's frames is its REPL: before the
run's first frame (what mpremote's raw REPL leaves) and after its last, the
ACTION STOP frame (the raw REPL's end of output, then its answers to what
arrives next). None of it is a bad frame. dabb985 dropped this file's first
version after one run logged "bad frame (overflow)": its mission had
outlived the board's run and read the raw REPL's output after STOP. Here
the run ends within the mission by construction (MAX_TICKS), the REPL is
made to answer after STOP (a Ctrl-A, then the next run started as mpremote
starts one), and each wait is on a condition: the board's STOP, then a
request of its next run answered; wall-clock limits are hang guards."""

from __future__ import annotations

import json
import logging
import subprocess
import time
from typing import Callable

import pytest

from bridge.behaviour_check import EXE, STEP_TIMEOUT_S, cli
from bridge.bodies import parse_assignment
from bridge.mission import MixedMission
from hil_tests.conftest import micropython_device  # noqa: F401 - a fixture
from sim_backend import scenario

TICKS = 12              # the board's run: MAX_TICKS
HANG_GUARD_S = 120.0
# mpremote's way into the raw REPL and a program started in it (exec --no-follow)
NEXT_RUN = b"\r\x03\r\x01import main; main.main()\x04"


def deploy_start(port: str, max_ticks: int) -> None:
    cli("deploy", "--behaviour", "aggregate", "--port", port, "--config", "NODE=1",
        "--config", f"MAX_TICKS={max_ticks}", "--config", "LINGER=2", "--start")


def serve(m: MixedMission, until: Callable[[], bool], what: str) -> None:
    """The mission's own paced loop until `until()`; once its scenario has
    ended, the board is still served (the mission's pump) until then."""
    m.run(until=lambda _: until())
    end = time.monotonic() + HANG_GUARD_S
    while not until():
        assert time.monotonic() < end, what
        m.link.pump(0.02)


def test_a_mission_after_deploy_start_reads_the_repl_as_no_bad_frame(
        micropython_device, caplog: pytest.LogCaptureFixture) -> None:  # noqa: F811
    relay = micropython_device
    deploy_start(relay.path, TICKS)
    caplog.set_level(logging.INFO, logger="bridge.serial.transport")
    sc = scenario.load("default").replace(behaviour="aggregate", agents=6)
    node, spec = parse_assignment(f"1=mpy://{relay.path}")
    with MixedMission(sc, 1, {node: spec}, tick_s=0.02) as m:
        serial, tether = m.opened[1].transport, m.link.tethers[1]
        serve(m, lambda: 1 in tether.stopped,
              "the board's run never ended: bad frames %r" % serial.bad_frames())
        # every tick of the run reached the host and was applied, once
        assert tether.stopped[1] == TICKS and tether.applied_ticks == TICKS
        answered = tether.answered
        relay.inject_to_child(NEXT_RUN)
        serve(m, lambda: tether.answered > answered,
              "the board's next run was never heard: bad frames %r" % serial.bad_frames())
        assert serial.bad_frames() == {}
        assert serial.skipped > 0          # the REPL's bytes between the two runs
    assert not [r for r in caplog.records if r.levelno >= logging.WARNING], caplog.text


def test_the_mission_command_after_deploy_start_logs_no_bad_frame(
        micropython_device) -> None:  # noqa: F811
    """The commands as a user types them. The board's run (12 ticks) ends
    within the mission's 100 whenever the board keeps pace: the mission then
    reads the REPL after STOP, the case dabb985 saw; the first test makes
    that case certain."""
    port = micropython_device.path
    deploy_start(port, TICKS)
    p = subprocess.run([EXE, "mission", "--body", f"1=mpy://{port}", "--behaviour", "aggregate",
                        "--robots", "6", "--tick-ms", "20", "--max-ticks", "100", "--json"],
                       capture_output=True, text=True, timeout=STEP_TIMEOUT_S)
    assert p.returncode in (0, 1), p.stderr
    assert "bad frame" not in p.stderr, p.stderr
    s = json.loads(p.stdout.strip().splitlines()[-1])
    assert s["bodies"]["1"].startswith("MicroPython robot"), s
    assert s["ticks"] > 0
