"""`touchswarm host --serial PORT`: the host process serves a robot on a
framed serial line (a pseudo-terminal standing in for a USB serial port)."""

from __future__ import annotations

import json
import os
import select
import subprocess
import sys
import time
import tty

from bridge.host.journal import Journal
from firmware_logic import framing
from firmware_logic import messages as msg


class FramedEnd:
    """The robot's end of the line: frames out, decoded messages in."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self.enc = framing.Encoder()
        self.dec = framing.Decoder()

    def send(self, node: int, kind: int, *fields: int) -> None:
        args = list(fields) + [0] * (6 - len(fields))
        n = self.enc.frame(kind, node, *args)
        os.write(self.fd, bytes(self.enc.out[:n]))

    def recv(self, timeout: float) -> list[tuple[int, int, tuple]]:
        out = []
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            r, _, _ = select.select([self.fd], [], [], max(0.0, end - time.monotonic()))
            if not r:
                break
            for b in os.read(self.fd, 256):
                if self.dec.feed(b):
                    out.append((self.dec.node, self.dec.kind,
                                tuple(self.dec.fields[:self.dec.nfields])))
            if out:
                break
        return out


def test_host_serves_a_serial_robot_and_journals_before_ack(tmp_path):
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    journal = tmp_path / "journal.sqlite"
    host = subprocess.Popen(
        [sys.executable, "-m", "bridge.cli", "host", "--serial", path, "--json",
         "--journal", str(journal), "--max-ticks", "150", "--tick-ms", "10",
         "--set", "objectWeight=3.0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    robot = FramedEnd(master)
    try:
        got = []
        deadline = time.monotonic() + 20
        while not any(k == msg.ACK and f[0] == 0 for _, k, f in got):
            assert time.monotonic() < deadline, "host never acknowledged HELLO"
            robot.send(7, msg.HELLO, 1, 100, 1)
            got += robot.recv(0.2)
        acks = 0
        while acks < 2:                                   # the second is a duplicate
            assert time.monotonic() < deadline, "host never acknowledged the touch"
            robot.send(7, msg.TOUCH, 1, 3, 4, 3, 5, 100)
            got = robot.recv(0.3)
            acks += sum(1 for _, k, f in got if k == msg.ACK and f[0] == 1)
        out, err = host.communicate(timeout=30)
    finally:
        if host.poll() is None:
            host.kill()
        os.close(master)
        os.close(slave)
    summary = json.loads(out)
    assert summary["touches"] == [[7, 1]], err          # (node, seq), once
    assert summary["duplicates"] >= 1
    assert summary["delivered"] is False             # one robot of power 1 < weight 3
    with Journal(journal) as db:
        assert [(r.node, r.fields[0], r.fields[3], r.fields[4])
                for r in db.reports(msg.TOUCH)] == [(7, 1, 3, 5)]


def test_host_needs_a_bus_or_a_serial_port():
    p = subprocess.run([sys.executable, "-m", "bridge.cli", "host"], capture_output=True,
                       text=True, timeout=60)
    assert p.returncode == 2 and "--bus URL and/or --serial PORT" in p.stderr
