"""A behaviour can be an installed package found by its entry point: a
distribution on the path, with the `touchswarm.behaviours` entry
point pip writes, is found by name, runs, sweeps, passes `firmware check`
(MicroPython), gives its DBC and records + replays over CAN, in processes
that know it only by that name."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

from sim_backend import registry

ROOT = Path(__file__).resolve().parents[1]
EXE = [sys.executable, "-m", "bridge.cli"]


def installed(tmp_path: Path) -> dict[str, str]:
    """`lab_swarm.crowd`, aggregate's scaffold renamed, installed as pip
    would: the package and its .dist-info with entry_points.txt on the path."""
    site = tmp_path / "site"
    pkg = site / "lab_swarm"
    pkg.mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    subprocess.run([*EXE, "behaviour", "new", "crowd", "--into", str(pkg)], check=True,
                   capture_output=True, cwd=ROOT)
    info = site / "lab_swarm-0.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: lab-swarm\nVersion: 0.1\n")
    (info / "entry_points.txt").write_text(
        "[touchswarm.behaviours]\ncrowd = lab_swarm.crowd\n")
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), str(ROOT)])}


def cli(env: dict[str, str], *args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([*EXE, *args], env=env, capture_output=True, text=True, cwd=cwd)


def test_an_installed_behaviour_is_found_by_name_and_passes_the_steps(tmp_path: Path) -> None:
    env = installed(tmp_path)
    assert "crowd" not in registry.names()            # not in this process: only installed
    r = cli(env, "behaviours", cwd=tmp_path)
    assert r.returncode == 0 and "crowd" in r.stdout and "BROKEN" not in r.stdout, r.stdout
    r = cli(env, "run", "--behaviour", "crowd", "--set", "maxTicks=300", "--json", cwd=tmp_path)
    assert r.returncode in (0, 1), r.stderr
    s = json.loads(r.stdout.strip().splitlines()[-1])
    assert s["robots"] == 20 and "largest" in s
    r = cli(env, "sweep", "--set", "behaviour=crowd", "--set", "maxTicks=100", "--seeds", "2",
            "--engine", "reference", "--no-plots", "--out", "sw", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert len((tmp_path / "sw" / "sweep.csv").read_text().splitlines()) == 3
    r = cli(env, "firmware", "check", "--behaviour", "crowd", cwd=tmp_path)
    assert r.returncode == 0 and r.stdout.rstrip().endswith("PASS"), r.stdout + r.stderr
    r = cli(env, "dbc", "--behaviour", "crowd", "--out", "crowd.dbc", cwd=tmp_path)
    assert r.returncode == 0 and "LEAVE" in (tmp_path / "crowd.dbc").read_text()
    r = cli(env, "run", "--behaviour", "crowd", "--set", "maxTicks=150", "--link", "can",
            "--record", "crowd.blf", cwd=tmp_path)
    assert r.returncode in (0, 1), r.stderr
    r = cli(env, "replay", "crowd.blf", cwd=tmp_path)
    assert r.returncode == 0, r.stdout + r.stderr


def test_an_installed_behaviour_that_cannot_import_is_one_line(tmp_path: Path) -> None:
    env = installed(tmp_path)
    shutil.rmtree(tmp_path / "site" / "lab_swarm" / "crowd")
    r = cli(env, "run", "--behaviour", "crowd", cwd=tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "crowd" in r.stderr and "lab_swarm.crowd" in r.stderr
