"""Liveness of the host: every port write has a timeout
(an SLCAN adapter that stops reading gives a typed LinkTimeoutError instead of
blocking for ever), the host goes on after one so its limits and a signal
still end the run, SIGTERM ends `touchswarm host` with its journal
consistent, and only frames from known nodes count as liveness."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
import time
import tty

import pytest

from bridge.host.journal import Journal
from bridge.host.process import HostProcess
from bridge.host.transport import CanTransport
from bridge.links import open_bus
from bridge.links.codec import encode
from bridge.links.errors import LinkTimeoutError
from firmware_logic import messages as msg
from tests.test_host_outcome import Ticks
from tests.test_journal import FakeTransport


def test_frames_from_unknown_nodes_do_not_keep_a_mission_alive() -> None:
    """A node that never said HELLO (noise, a forger) sends every tick: the
    bus limit fires anyway (it once never did)."""
    class Noise(FakeTransport):
        def poll(self, timeout):
            return [(99, msg.HEARTBEAT, (1, 0, 0, 0, 0))]

    h = HostProcess(Noise(), weight=100)
    s = h.run(clock=Ticks(0.004), bus_timeout=0.5, max_ticks=1000)
    assert s["gave_up_on"] == "bus" and s["outcome"] == "stalled" and s["ticks"] < 1000
    assert sum(s["bad_frames"].values()) > 0


class Blocked(FakeTransport):
    """A link whose writes all time out (an adapter that stopped reading)."""

    def send(self, node, kind, fields):
        raise LinkTimeoutError("host send: timed out")


def test_a_write_timeout_is_counted_and_the_node_limit_still_fires() -> None:
    tr = Blocked()
    h = HostProcess(tr, weight=100)
    h.handle([(4, msg.HELLO, (1, 100, 1))])
    h.step()                                    # its ACK times out: counted, not raised
    h.handle([(4, msg.TOUCH, (1, 2, 2, 3, 2, 100))])
    s = h.run(clock=Ticks(0.004), node_timeout=0.3, max_ticks=1000)
    assert s["gave_up_on"] == "node" and s["write_timeouts"] > 1 and s["ticks"] < 1000


def test_an_slcan_adapter_that_stops_reading_gives_a_typed_timeout(tmp_path) -> None:
    master, slave = os.openpty()
    tty.setraw(slave)
    try:
        bus = open_bus(f"slcan://{os.ttyname(slave)}?settle_ms=0")
        with CanTransport(bus) as tr:
            with pytest.raises(LinkTimeoutError, match="stopped reading"):
                for _ in range(200_000):         # until the pty's buffer is full
                    tr.send(5, msg.ACK, (1,))
    finally:
        os.close(master)
        os.close(slave)


def slcan_line(node: int, kind: int, fields: tuple) -> bytes:
    f = encode(node, kind, fields)
    return b"t%03X%d%s\r" % (f.arbitration_id, f.dlc, f.data.hex().upper().encode())


def test_sigterm_ends_a_host_whose_adapter_stopped_reading(tmp_path) -> None:
    """The adapter (a pty nobody reads from the host's side) forwards robots'
    HELLOs but takes none of the host's ACKs: the host's writes time out, and
    SIGTERM still ends it, exit 1, outcome stopped, its journal readable."""
    master, slave = os.openpty()
    tty.setraw(slave)
    jp = tmp_path / "j.sqlite"
    host = subprocess.Popen(
        [sys.executable, "-m", "bridge.cli", "host", "--bus",
         f"slcan://{os.ttyname(slave)}?settle_ms=0", "--journal", str(jp), "--json",
         "--tick-ms", "2", "--bus-timeout", "0", "--node-timeout", "0"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    hellos = b"".join(slcan_line(n, msg.HELLO, (1, 100, 1)) for n in range(1, 101))
    timed_out = threading.Event()
    lines: list[str] = []

    def watch() -> None:
        for line in host.stderr:
            lines.append(line)
            if "write timed out" in line:
                timed_out.set()
    threading.Thread(target=watch, daemon=True).start()
    try:
        os.set_blocking(master, False)
        # robots keep saying HELLO (each gets an ACK the adapter never takes)
        # until the host says a write timed out (a condition, not a delay)
        give_up = time.monotonic() + 120          # a hang's cap, no timing assert
        while not timed_out.wait(0.01) and host.poll() is None and time.monotonic() < give_up:
            try:
                os.write(master, hellos)
            except BlockingIOError:
                pass
        assert timed_out.is_set(), "".join(lines)
        host.send_signal(signal.SIGTERM)
        out = host.stdout.read()
        rc = host.wait(60)
    finally:
        if host.poll() is None:
            host.kill()
            host.wait()
        os.close(master)
        os.close(slave)
    assert rc == 1, "".join(lines)
    s = json.loads(out.strip().splitlines()[-1])
    assert s["outcome"] == "stopped" and s["write_timeouts"] >= 1
    assert s["reason"].startswith("stopped by a signal")
    with Journal(jp) as j:                  # consistent, and the lock was released
        assert j.outcome()["outcome"] == "stopped" and len(j.nodes()) == 100
