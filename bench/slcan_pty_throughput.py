"""Robots -> host frames/s over the SLCAN face on a pty, both processes on ONE core.

The robots' side is `slcan-pty://PATH` (bridge/links/slcan_pty.py) in a child
process; the host's side is `CanTransport(slcan://PATH)` in this process, read
the way the host's run loop reads it (`poll(0.01)` over and over). Both
processes are pinned to the same CPU, so the figure is what one core gives the
whole path (face formatting and writing, the pty, python-can's slcan reader,
the validating decoder).

Three loads, each of HEARTBEAT frames (8 data bytes, the longest kind):
  flood   N frames as fast as the face can write them (it waits while the pty
          is full rather than drop): the path's ceiling;
  paced   4,500 frames/s (a saturated 500 kbit/s bus) and 9,000 frames/s for
          2 s each, sent in 1 ms bursts (every frame due by then): is every
          frame read, and how far behind is the reader at the end.
Also the longest `poll(0.01)` call seen (a poll must return by its deadline).
Prints one JSON object. Reference: 500 kbit/s carries about 4,500 such frames/s.
"""

from __future__ import annotations

import json
import os
import select
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bridge.host.transport import CanTransport  # noqa: E402
from bridge.links import open_bus  # noqa: E402
from bridge.links.codec import encode  # noqa: E402
from firmware_logic import messages as msg  # noqa: E402

BUS_500K = 4500
FLOOD = 40_000
PACED_S = 2.0
POLL = 0.01
IDLE_END = 1.0        # the reader stops this long after the last frame


def pin(cpu: int) -> None:
    if hasattr(os, "sched_setaffinity"):
        os.sched_setaffinity(0, {cpu})


def frames(n: int) -> list:
    return [encode(i % 100 + 1, msg.HEARTBEAT, (4, i % 4000, -(i % 3000), i % 360, i % 255))
            for i in range(n)]


# -- the robots' side (child process) --------------------------------------------


def wait_writable(bus) -> None:
    """Bench-side flow control: let the pty drain instead of dropping frames."""
    while len(bus.pending) > 16 * 1024:
        select.select([], [bus.master], [], 1.0)
        bus._flush_out()


def face(path: str, mode: str, arg: float, cpu: int) -> None:
    pin(cpu)
    with open_bus(f"slcan-pty://{path}") as bus:
        print("ready", flush=True)
        end = time.monotonic() + 10
        while not bus.is_open and time.monotonic() < end:   # the host's O command
            bus.recv(0.01)
        sys.stdin.readline()                                  # go
        t_first = time.monotonic()
        if mode == "flood":
            for f in frames(int(arg)):
                bus.send(f)
                wait_writable(bus)
            t_last = time.monotonic()
        else:
            rate = arg
            fs = frames(int(rate * PACED_S))
            t0 = time.monotonic()
            i = 0
            while i < len(fs):
                due = min(len(fs), int((time.monotonic() - t0) * rate) + 1)
                for f in fs[i:due]:        # every frame due by now, as a bus would deliver
                    bus.send(f)
                t_last = time.monotonic()
                i = max(i, due)
                wait_writable(bus)
                bus.recv(0.001)            # 1 ms between bursts (also takes host commands)
        while bus.pending:
            select.select([], [bus.master], [], 1.0)
            bus._flush_out()
        # CLOCK_MONOTONIC is system-wide: the host compares it with its own
        print(json.dumps({"dropped": bus.dropped, "t_first": t_first,
                          "t_last": t_last}), flush=True)
        sys.stdin.readline()                                  # the host has read all


# -- the host's side ---------------------------------------------------------------


def measure(mode: str, arg: float, cpu: int, tmp: Path) -> dict:
    path = tmp / f"ada-{mode}-{int(arg)}"
    child = subprocess.Popen([sys.executable, __file__, "--face", str(path), mode, str(arg),
                              str(cpu)], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                             text=True)
    try:
        assert child.stdout.readline().strip() == "ready"
        expected = int(arg) if mode == "flood" else int(arg * PACED_S)
        with CanTransport(open_bus(f"slcan://{path}?settle_ms=0")) as tr:
            child.stdin.write("go\n")
            child.stdin.flush()
            got = 0
            first = last = None
            worst_poll = 0.0
            t_go = time.monotonic()
            while True:
                t = time.monotonic()
                out = tr.poll(POLL)
                done = time.monotonic()
                worst_poll = max(worst_poll, done - t)
                if out:
                    got += len(out)
                    first = first if first is not None else t
                    last = done
                if got >= expected:
                    break
                if (last or t_go) + IDLE_END + (5.0 if last is None else 0.0) < done:
                    break
        face_report = json.loads(child.stdout.readline())
        child.stdin.write("end\n")
        child.stdin.flush()
        child.wait(10)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait(10)
    span = (last - first) if first is not None and last is not None and last > first else 0.0
    sent_span = face_report["t_last"] - face_report["t_first"]
    return {"expected": expected, "received": got, "dropped_by_face": face_report["dropped"],
            "frames_per_s": round(got / span) if span else None,
            "offered_frames_per_s": round(expected / sent_span) if sent_span > 0 else None,
            "last_frame_read_ms_after_sent": round((last - face_report["t_last"]) * 1000, 1)
            if last is not None else None,
            "zero_loss": got == expected,
            "worst_poll_ms": round(worst_poll * 1000, 2)}


def main() -> None:
    cpu = min(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else 0
    pin(cpu)
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        flood = measure("flood", FLOOD, cpu, tmp)
        paced = {str(r): measure("paced", r, cpu, tmp) for r in (BUS_500K, 2 * BUS_500K)}
    print(json.dumps({
        "bench": "slcan_pty_throughput",
        "cpu": cpu,
        "flood_frames": FLOOD,
        "flood": flood,
        "paced": paced,
        "bus_500kbit_frames_per_s": BUS_500K,
        "keeps_up_with_500kbit_bus": bool(flood["frames_per_s"]
                                          and flood["frames_per_s"] >= BUS_500K
                                          and paced[str(BUS_500K)]["zero_loss"]),
    }, sort_keys=True))


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--face":
        face(sys.argv[2], sys.argv[3], float(sys.argv[4]), int(sys.argv[5]))
    else:
        main()
