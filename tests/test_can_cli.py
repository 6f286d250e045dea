"""The host and robots commands end to end in one process (virtual bus)."""

import json
import threading

from bridge.cli import main
from bridge.host.journal import Journal
from bridge.links.canlink import private_channel
from firmware_logic.behaviours.thesis.coordinator import Touch


def test_host_gives_up_without_robots_and_resumes_into_a_new_journal(tmp_path, capsys):
    old = tmp_path / "old.sqlite"
    with Journal(old) as j:
        j.add_node(2, 1, 100)
        j.add_touch(Touch(2, 1, 3, 3, 4, 3, 100, 9))
    new = tmp_path / "new.sqlite"
    rc = main(["host", "--bus", f"virtual://{private_channel()}", "--resume", str(old),
               "--journal", str(new), "--max-ticks", "3", "--tick-ms", "1", "--json"])
    cap = capsys.readouterr()
    assert rc == 1
    s = json.loads(cap.out)
    assert s["resumed"] == 1 and s["touches"] == [[2, 1]] and not s["delivered"]
    assert "resumed 1 touches" in cap.err and "gave up after 3 ticks" in cap.err
    with Journal(new) as j:
        assert [t.as_tuple() for t in j.touches()] == [(2, 1, 3, 3, 4, 3, 100, 9)]
    assert main(["host", "--bus", "virtual://x", "--resume", str(tmp_path / "none")]) == 2


def test_robots_and_host_commands_on_one_virtual_channel(tmp_path, capsys):
    ch = private_channel()
    res = {}
    jp = tmp_path / "j.sqlite"
    # robots repeat HELLO until acknowledged, so start-up order does not matter
    th = threading.Thread(target=lambda: res.update(rc=main(
        ["host", "--bus", f"virtual://{ch}", "--journal", str(jp), "--tick-ms", "2",
         "--max-ticks", "5000"])))
    th.start()
    rc = main(["robots", "--bus", f"virtual://{ch}", "--tick-ms", "2", "--linger-ms", "50",
               "--json", "--loss", "0.1", "--reorder", "3"])
    th.join(60)
    out = capsys.readouterr().out
    assert rc == 0 and res["rc"] == 0
    assert "DELIVERED" in out
    robots = json.loads([line for line in out.splitlines() if line.startswith("{")][-1])
    with Journal(jp) as j:
        assert sorted([t.node, t.seq] for t in j.touches()) == sorted(robots["reported"])
