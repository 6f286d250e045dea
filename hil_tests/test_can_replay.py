"""Golden recordings (hil_tests/data/) replay with their expected summaries.

A change to the firmware's or the coordinator's decisions shows up here as a
divergence. Regenerate with `touchswarm run ... --record` (see docs/protocol.md).
"""

import json
from pathlib import Path

import pytest

from bridge.record.replay import replay

DATA = Path(__file__).parent / "data"
GOLDEN = sorted(p for p in DATA.iterdir() if p.name.startswith("golden_")
                and not p.name.endswith(".json"))


def test_there_are_goldens():
    assert len(GOLDEN) >= 2


@pytest.mark.parametrize("path", GOLDEN, ids=lambda p: p.name)
def test_golden_replay(path):
    s = replay(path)
    s.pop("recording")
    want = json.loads(Path(str(path) + ".expected.json").read_text())
    assert s == want
    recorded = json.loads(Path(str(path) + ".json").read_text())["summary"]
    assert s["delivered_tick"] == recorded["home_tick"]
    assert s["touches"] == len(recorded["touches"])
