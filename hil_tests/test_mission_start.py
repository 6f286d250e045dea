"""`touchswarm deploy --start` then `touchswarm mission --body 1=mpy://PORT`,
on MicroPython's unix port behind a pty, as a user runs the two: the REPL's
output deploy leaves on the line is no bad frame (no warning). The pty
loses what the board writes while no one holds the port open, so this
fixture cannot keep the REPL's leftover for the mission as a USB board does:
tests/test_serial_transport.py writes it on a pty the transport holds,
and checks that garbage after framing started is still counted."""

from __future__ import annotations

import json
import subprocess

from bridge.behaviour_check import EXE, STEP_TIMEOUT_S, cli
from hil_tests.conftest import micropython_device  # noqa: F401 - a fixture


def test_a_mission_after_deploy_start_reports_no_bad_frame(micropython_device):  # noqa: F811
    port = micropython_device.path
    cli("deploy", "--behaviour", "aggregate", "--port", port, "--config", "NODE=1",
        "--config", "MAX_TICKS=300", "--config", "LINGER=2", "--start")
    p = subprocess.run([EXE, "mission", "--body", f"1=mpy://{port}", "--behaviour", "aggregate",
                        "--robots", "6", "--tick-ms", "20", "--max-ticks", "100", "--json"],
                       capture_output=True, text=True, timeout=STEP_TIMEOUT_S)
    assert p.returncode in (0, 1), p.stderr
    assert "bad frame" not in p.stderr, p.stderr
    s = json.loads(p.stdout.strip().splitlines()[-1])
    assert s["bodies"]["1"].startswith("MicroPython robot"), s
    assert s["ticks"] > 0
