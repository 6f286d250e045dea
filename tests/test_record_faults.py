"""A recording of a faulty run replays to what happened:
`run --record` under every fault kind, then `replay`, gives 0 divergences.

The link's faults act between the robots and the host (`--link can`), the
body's inside the simulated robot (in process); a recording holds the
firmware's decisions before any fault filter and what each side received
after the faults (bridge/record/recorder.py)."""

import json
from pathlib import Path

import pytest

from bridge.cli import main
from bridge.record.replay import load, replay
from sim_backend import faults
from sim_backend.scenario import LINK_FAULT_KEYS

SMALL = ["--robots", "6", "--set", "objectWeight=2", "--set", "maxTicks=120", "--seed", "3"]

# one setting per fault kind, strong enough to bite within SMALL's 120 ticks
FAULTS = {
    "linkLoss": "0.2",
    "linkDelay": "4",
    "linkDup": "0.3",
    "linkReorder": "3",
    "deathRate": "0.5",
    "deadlockRate": "0.5",
    "ignoreFieldRate": "0.5",
    "ignoreHostRate": "0.5",
    "randomRate": "0.5",
    "probeMiss": "0.3",
    "probeGhost": "0.1",
    "fieldNoise": "3",
}


def test_every_fault_kind_is_covered():
    assert set(FAULTS) == set(LINK_FAULT_KEYS) | set(faults.RATE_KEYS) | {"fieldNoise"}


@pytest.mark.parametrize("key", sorted(FAULTS))
def test_a_faulty_run_replays_with_no_divergence(tmp_path, key, capsys):
    f = tmp_path / "run.blf"
    link = ["--link", "can"] if key in LINK_FAULT_KEYS else []
    extra = ["--set", "faultWindow=40"] if key in ("deathRate", "deadlockRate") else []
    main(["run", *SMALL, *link, *extra, "--set", f"{key}={FAULTS[key]}",
          "--record", str(f), "--json"])
    run = json.loads(capsys.readouterr().out)
    s = replay(f)
    assert s["differences"] == [] and s["divergences"] == 0
    assert s["ticks"] == run["ticks"] and s["delivered_tick"] == run["home_tick"]
    assert s["touches"] == len(run["touches"])


def test_the_recording_holds_what_the_host_received_and_what_the_robots_sent(tmp_path):
    """Under loss the host received fewer frames than the robots sent: both
    are in the recording (the firmware's decisions are not filtered)."""
    f = tmp_path / "lossy.log"
    main(["run", *SMALL, "--link", "can", "--set", "linkLoss=0.3", "--record", str(f)])
    rec = load(f)
    sent = sum(len(v) for v in rec.up.values())
    received = sum(len(rec.host_in.get(t, rec.up.get(t, []))) for t in rec.ticks)
    assert rec.host_in and rec.recv_fields
    assert received < sent


def test_a_dead_robots_decisions_are_recorded(tmp_path):
    f = tmp_path / "dead.log"
    main(["run", *SMALL, "--set", "deathRate=0.5", "--set", "faultWindow=5",
          "--record", str(f)])
    rec = load(f)
    from sim_backend.scenario import validate
    die = faults.plan(validate(dict(rec.meta["scenario"])), 3)[0]
    dead = [i + 1 for i, d in enumerate(die) if d != faults.NEVER]
    assert dead
    # a dead robot's firmware still decides: the recording holds its decisions
    for n in dead:
        assert any(t > die[n - 1] for t in rec.actions[n]), n


def test_the_documented_lossy_recording_replays(tmp_path, capsys, monkeypatch):
    """docs/protocol.md's commands: a lossy CAN run recorded, then replayed."""
    import shlex
    doc = (Path(__file__).resolve().parents[1] / "docs" / "protocol.md").read_text()
    cmds = [shlex.split(line.split("#")[0]) for line in doc.splitlines()
            if line.startswith("touchswarm ") and "lossy.blf" in line]
    assert [c[1] for c in cmds] == ["run", "replay"] and "linkLoss=0.05" in cmds[0]
    monkeypatch.chdir(tmp_path)
    main(cmds[0][1:])
    capsys.readouterr()
    assert main(cmds[1][1:]) == 0
    out = capsys.readouterr().out
    assert "0 divergences" in out and "delivered at tick" in out
