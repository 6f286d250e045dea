"""The check that every README and guide command was run (tests/doc_commands.py,
applied by conftest.py after the whole suite) finds what it should."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from tests import doc_commands as d


def test_the_docs_commands_are_read() -> None:
    lines = d.documented()
    files = {f for f, _ in lines}
    assert files == set(d.DOCS) and len(lines) >= 40
    assert ("README.md", "run --scenario ant --seed 7") in lines


def test_a_form_keeps_names_and_keys_and_drops_paths_and_numbers() -> None:
    f = d.form(["run", "--scenario", "my.toml", "--set", "sigRadius=7", "--seed", "3",
                "--link", "can", "--json"])
    assert f.words == ("run",)
    assert f.options == {("--scenario", None), ("--set", "sigRadius"), ("--seed", None),
                         ("--link", "can"), ("--json", None)}
    assert d.form(["firmware", "check", "--behaviour", "/tmp/x"]).words == ("firmware", "check")


def test_a_run_covers_a_doc_command_only_in_the_same_form() -> None:
    doc = d.form(["run", "--scenario", "ant", "--seed", "7"])
    assert doc.covered_by(d.form(["run", "--scenario", "ant", "--seed", "2", "--json",
                                  "--set", "maxTicks=50"]))
    assert not doc.covered_by(d.form(["run", "--scenario", "X", "--seed", "7"]))
    assert not doc.covered_by(d.form(["run", "--scenario", "ant"]))
    # an option that changes what runs is not test size
    assert not doc.covered_by(d.form(["run", "--scenario", "ant", "--seed", "7",
                                      "--set", "wrap=true"]))
    assert not doc.covered_by(d.form(["sweep", "--scenario", "ant", "--seed", "7"]))


def test_the_cli_logs_what_ran_and_uncovered_names_the_rest(tmp_path: Path) -> None:
    log = tmp_path / "argv.jsonl"
    env = {"TOUCHSWARM_ARGV_LOG": str(log), "PATH": "/usr/bin:/bin"}
    exe = [sys.executable, "-m", "bridge.cli"]
    assert subprocess.run([*exe, "scenarios"], env=env, capture_output=True).returncode == 0
    assert subprocess.run([*exe, "run", "--bogus"], env=env, capture_output=True).returncode == 2
    recs = [json.loads(x) for x in log.read_text().splitlines()]
    assert recs == [{"argv": ["scenarios"], "rc": 0}, {"argv": ["run", "--bogus"], "rc": 2}]
    missing = d.uncovered(log)
    assert not any(m.endswith("touchswarm scenarios") for m in missing)
    assert "README.md: touchswarm run --scenario ant --seed 7" in missing
