"""`touchswarm host --behaviour NAME` builds its coordinator through the
registry, and refuses in one line a behaviour whose coordinator lacks what the
host's journal, resume and liveness checks need."""

from __future__ import annotations

import pytest

from bridge.cli import main


def test_host_runs_the_thesis_through_the_registry_and_refuses_aggregate(
        capsys: pytest.CaptureFixture[str]) -> None:
    from bridge.errors import UsageError
    from bridge.host.process import HostProcess, host_behaviour
    from tests.test_journal import FakeTransport

    h = HostProcess(FakeTransport(), weight=500, behaviour="thesis")
    assert h.behaviour.name == "thesis"
    assert type(h.coord).__module__ == "firmware_logic.behaviours.thesis.coordinator"
    # the aggregate coordinator journals no nodes and keeps no transport state:
    # refused in one line, naming what it lacks, before any port is opened
    with pytest.raises(UsageError, match="aggregate.*lacks journal_node, on_reject"):
        host_behaviour("aggregate")
    assert main(["host", "--behaviour", "aggregate", "--bus", "slcan:///nonexistent"]) == 2
    err = capsys.readouterr().err.strip()
    assert "cannot run in the host process" in err and "\n" not in err
    assert main(["host", "--behaviour", "nosuch", "--bus", "slcan:///nonexistent"]) == 2
    assert "not an installed behaviour" in capsys.readouterr().err
