"""bench/sweep_wall.py's options as docs/performance.md uses them (its
figures are benches, not tests: only that the command line takes them)."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_sweep_wall_takes_the_documented_options():
    done = subprocess.run([sys.executable, "bench/sweep_wall.py", "--help"], cwd=ROOT,
                          capture_output=True, text=True, timeout=60, check=True)
    for option in ("--skip-fresh", "--skip-run", "--reps", "--tree", "--mesa-runs",
                   "--sweep-runs"):
        assert option in done.stdout
