"""README's bus and board lines, as written, with the machine's stand-ins:
`socketcan://can0` is the project's SLCAN face on a pty (this kernel has no
vcan; the robots' process owns the adapter, the host opens it as a serial
SLCAN adapter) and `/dev/ttyACM0` the MicroPython unix port behind a pty.

    touchswarm robots --bus socketcan://can0 --behaviour aggregate
    touchswarm host --bus socketcan://can0 --behaviour aggregate --journal agg.sqlite
    touchswarm view --journal touches.sqlite
    touchswarm deploy --port /dev/ttyACM0 --config HEAP_CHECK=20
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

from bridge.cli import main
from hil_tests.test_can_host_restart import EXE, lines_of, stop_all, wait_for

PACE = ["--tick-ms", "4"]


def test_readme_aggregate_robots_and_host_then_the_journal_view(tmp_path: Path) -> None:
    adapter = tmp_path / "can0"
    journal = tmp_path / "agg.sqlite"
    robots = subprocess.Popen([EXE, "robots", "--bus", f"slcan-pty://{adapter}",
                               "--behaviour", "aggregate", *PACE, "--linger-ms", "1500",
                               "--json"],
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    procs = [robots]
    try:
        assert wait_for(lines_of(robots.stderr), lambda s: "robots on" in s[-1], 60)
        host = subprocess.Popen([EXE, "host", "--bus", f"slcan://{adapter}?settle_ms=0",
                                 "--behaviour", "aggregate", "--journal", str(journal),
                                 *PACE, "--json"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        procs.append(host)
        out, err = host.communicate(timeout=300)
        assert host.returncode == 0, err
        robots.communicate(timeout=120)
    finally:
        stop_all(procs)
    assert json.loads(out.strip().splitlines()[-1])["delivered"]
    shot = tmp_path / "journal.png"
    assert main(["view", "--journal", str(journal), "--screenshot", str(shot)]) == 0
    assert shot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_readme_deploy_with_the_heap_check(micropython_device) -> None:
    assert main(["deploy", "--port", micropython_device.path, "--config", "HEAP_CHECK=20"]) == 0
    config = (micropython_device.flash / "robot_config.py").read_text()
    assert "HEAP_CHECK = 20" in config
