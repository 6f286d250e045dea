"""The host and robots commands end to end in one process (the robots' SLCAN
face on a pty: python-can's virtual bus is refused by both commands, since it
does not cross processes)."""

import json
import threading
import time

from bridge.cli import main
from bridge.host.journal import Journal
from bridge.links import open_bus
from firmware_logic import messages as msg


def test_host_gives_up_without_robots_and_resumes_into_a_new_journal(tmp_path, capsys):
    old = tmp_path / "old.sqlite"
    with Journal(old) as j:
        j.bind("thesis")
        j.add_report(2, msg.HELLO, (1, 100, 1), 8)
        j.add_report(2, msg.TOUCH, (1, 3, 3, 4, 3, 100), 9)
    new = tmp_path / "new.sqlite"
    with open_bus(f"slcan-pty://{tmp_path / 'ada'}"):        # an adapter, no robots
        rc = main(["host", "--bus", f"slcan://{tmp_path / 'ada'}?settle_ms=0", "--resume",
                   str(old), "--journal", str(new), "--max-ticks", "3", "--tick-ms", "1",
                   "--json"])
    cap = capsys.readouterr()
    assert rc == 1
    s = json.loads(cap.out)
    assert s["resumed"] == 1 and s["touches"] == [[2, 1]] and not s["delivered"]
    assert "resumed 1 touches" in cap.err and "gave up after 3 ticks" in cap.err
    with Journal(new) as j:
        assert [r.fields for r in j.reports(msg.TOUCH)] == [(1, 3, 3, 4, 3, 100)]
    assert main(["host", "--bus", "virtual://x", "--resume", str(tmp_path / "none")]) == 2


def test_robots_and_host_commands_over_the_slcan_pty_face(tmp_path, capsys):
    ada = tmp_path / "ada"
    res = {}
    jp = tmp_path / "j.sqlite"
    # robots repeat HELLO until acknowledged, so start-up order does not matter
    th = threading.Thread(target=lambda: res.update(rc=main(
        ["robots", "--bus", f"slcan-pty://{ada}", "--tick-ms", "2", "--linger-ms", "50",
         "--json", "--loss", "0.1", "--reorder", "3"])))
    th.start()
    end = time.monotonic() + 20
    while not ada.is_symlink() and th.is_alive() and time.monotonic() < end:
        time.sleep(0.005)                       # wait for the face (a condition, not a delay)
    rc = main(["host", "--bus", f"slcan://{ada}?settle_ms=0", "--journal", str(jp),
               "--tick-ms", "2", "--max-ticks", "5000"])
    th.join(60)
    out = capsys.readouterr().out
    assert rc == 0 and res["rc"] == 0
    assert "DELIVERED" in out
    robots = json.loads([line for line in out.splitlines() if line.startswith("{")][-1])
    with Journal(jp) as j:
        journalled = [(r.node, r.fields[0]) for r in j.reports(msg.TOUCH)]
    # the host ACKs a touch only once it is journalled: every robot's latest
    # touch that was acknowledged is in the journal, once; a touch still
    # unacknowledged when the host ended (a robot that grasped again after
    # delivery, or whose report was lost) may not be, and every journalled
    # touch is one its robot made (its sequence number at most the robot's last)
    latest = {node: seq for node, seq in robots["reported"]}
    acked = {(n, s) for n, s in latest.items() if n not in robots["unacked"]}
    assert len(journalled) == len(set(journalled)) and acked <= set(journalled)
    assert all(n in latest and s <= latest[n] for n, s in journalled)
    assert len(acked) >= 4


def test_host_and_robots_refuse_the_in_process_virtual_bus(capsys):
    for cmd in ("host", "robots"):
        assert main([cmd, "--bus", "virtual://x"]) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
        assert "does not cross processes" in err and "slcan-pty://" in err
