"""Deployer retries mpremote only when it failed before running anything."""
from __future__ import annotations

import stat
import sys
from pathlib import Path

import pytest

from bridge.serial.deploy import RAW_REPL_TRIES, DeployError, Deployer

FAKE = """#!{python}
import sys
from pathlib import Path
calls = Path({calls!r})
n = int(calls.read_text()) + 1 if calls.exists() else 1
calls.write_text(str(n))
if n <= {fail_first}:
    print({message!r}, file=sys.stderr)
    sys.exit(1)
print("ran", " ".join(sys.argv[1:]))
"""


def fake_mpremote(tmp_path: Path, fail_first: int, message: str) -> tuple[str, Path]:
    calls = tmp_path / "calls"
    script = tmp_path / "mpremote"
    script.write_text(FAKE.format(python=sys.executable, calls=str(calls),
                                  fail_first=fail_first, message=message))
    script.chmod(script.stat().st_mode | stat.S_IEXEC)
    return str(script), calls


def test_a_board_slow_to_enter_the_raw_repl_is_retried_and_runs_once(tmp_path: Path) -> None:
    tool, calls = fake_mpremote(tmp_path, RAW_REPL_TRIES - 1,
                                "mpremote.transport.TransportError: could not enter raw repl")
    out = Deployer("/dev/null", mpy_cross="mpy-cross", mpremote=tool).exec("print(1)")
    assert out.startswith("ran connect port:/dev/null resume exec")
    assert int(calls.read_text()) == RAW_REPL_TRIES


def test_a_board_that_never_answers_fails_after_the_last_try(tmp_path: Path) -> None:
    tool, calls = fake_mpremote(tmp_path, 99, "TransportError: could not enter raw repl")
    with pytest.raises(DeployError, match="could not enter raw repl"):
        Deployer("/dev/null", mpy_cross="mpy-cross", mpremote=tool).exec("print(1)")
    assert int(calls.read_text()) == RAW_REPL_TRIES


def test_other_failures_are_not_retried(tmp_path: Path) -> None:
    # the code may have run: running it again could repeat a side effect
    tool, calls = fake_mpremote(tmp_path, 1, "Traceback: NameError: name 'x' isn't defined")
    with pytest.raises(DeployError, match="NameError"):
        Deployer("/dev/null", mpy_cross="mpy-cross", mpremote=tool).exec("x")
    assert int(calls.read_text()) == 1
