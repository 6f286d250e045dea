"""Host throughput on a python-can virtual bus, beside a bare receive loop.

Every robot first announces itself (HELLO) and reports one touch (TOUCH),
each journalled to SQLite (WAL, synchronous=FULL: one fsync per touch) before
its ACK; that phase is timed on its own (ms per journalled touch). Then N
HEARTBEAT frames are loaded onto a virtual channel and timed twice: (a) a bare
python-can `recv` loop draining them, (b) the host process's receive path
draining the same frames: CanTransport.poll (validating decoder, bad-frame
accounting) + HostProcess.handle (announcement check, coordinator) + one host
tick per batch. Zero loss is checked: every frame sent is received and handled.
The host path is timed twice: plain, and keyed (host and robots with keys:
every HELLO, TOUCH and HEARTBEAT sealed as keyed robots send them and verified
by the host, its ACKs sealed). Prints one JSON object. Reference: a saturated
1 Mbit/s bus carries at most about 9,000 8-byte frames/s; targets: the host,
keyed, >= TARGET (0.2) of the bare loop in the same run, and plain >= 4x
that bus. `--profile` prints a cProfile of each timed drain on stderr.
"""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from bridge.host.journal import Journal  # noqa: E402
from bridge.host.process import HostProcess  # noqa: E402
from bridge.host.transport import CanTransport  # noqa: E402
from bridge.links import open_bus  # noqa: E402
from bridge.links.codec import encode  # noqa: E402
from firmware_logic import messages as msg  # noqa: E402

ROBOTS = 100
N = 200_000
REPEATS = 3
BUS_MAX = 9000
PROFILE = "--profile" in sys.argv     # cProfile of the timed host drain, on stderr
TARGET = 0.2       # the host, with authentication, >= this share of the bare loop


KEYS = {r: bytes([r, 0x5C]) * 8 for r in range(1, ROBOTS + 1)}


def touch(r: int) -> tuple:
    """A valid touch of robot r: each robot its own segment (one holder each)."""
    x = (r - 1) % 10 * 2
    y = (r - 1) // 10 * 2
    return (1, x, y, x + 1, y, 100)


def hellos(robots=None) -> list:
    out = [encode(r, msg.HELLO, (1, 100, 1)) for r in range(1, ROBOTS + 1)]
    return out if robots is None else [robots.hello(f) for f in out]


def touches(robots=None) -> list:
    if robots is None:
        return [encode(r, msg.TOUCH, touch(r)) for r in range(1, ROBOTS + 1)]
    return [robots.seal_report(r, msg.TOUCH, touch(r)) for r in range(1, ROBOTS + 1)]


def frames(n: int, robots=None) -> list:
    """n HEARTBEATs; with `robots` (a secoc.Opener that took a host command
    for each robot) sealed as keyed robots send them."""
    out = []
    i = 0
    while len(out) < n:
        r = i % ROBOTS + 1
        f = (0, (i * 7) % 4000, -(i % 3000), i % 360, 0)
        out.append(encode(r, msg.HEARTBEAT, f) if robots is None
                   else robots.seal_report(r, msg.HEARTBEAT, f))
        i += 1
    return out


def bare(ch: str, fs: list) -> float:
    with open_bus(f"virtual://{ch}") as tx, open_bus(f"virtual://{ch}") as rx:
        for f in fs:
            tx.send(f)
        t = time.perf_counter()
        n = 0
        while rx.recv(0.0) is not None:
            n += 1
        dt = time.perf_counter() - t
    assert n == len(fs), (n, len(fs))
    return n / dt


def drain(tr: CanTransport, h: HostProcess) -> None:
    while True:
        got = tr.poll(0.0)
        if not got:
            break
        h.handle(got)
        h.step()


def host(ch: str, n: int, tmp: Path, keyed: bool = False) -> tuple[float, dict]:
    """The host's receive path on n HEARTBEATs; keyed: host and robots with
    keys (every report sealed by the robots' side and verified by the host)."""
    from bridge.links.codec import BadFrames
    from bridge.links.secoc import Opener, Sealer
    sealer = Sealer(KEYS) if keyed else None
    robots = Opener(KEYS, BadFrames("robots")) if keyed else None
    with open_bus(f"virtual://{ch}") as tx, \
            CanTransport(open_bus(f"virtual://{ch}"), sealer=sealer) as tr, \
            Journal(tmp / f"{ch}.sqlite") as j:
        h = HostProcess(tr, weight=10 ** 6, journal=j)
        t = time.perf_counter()
        for f in hellos(robots):
            tx.send(f)
        drain(tr, h)
        if robots is not None:      # the robots take their HELLOs' ACKs (their H)
            while (cmd := tx.recv(0.0)) is not None:
                robots.open(cmd)
        for f in touches(robots):
            tx.send(f)
        drain(tr, h)
        journal_ms = (time.perf_counter() - t) * 1000 / ROBOTS
        assert len(j.reports(msg.TOUCH)) == ROBOTS and h.messages == 2 * ROBOTS, \
            (len(j.reports(msg.TOUCH)), h.messages, h.bad_frames())
        fs = frames(n, robots)
        h.messages = 0
        tr.frames_in = 0
        for f in fs:
            tx.send(f)
        t = time.perf_counter()
        if PROFILE:
            import cProfile
            import pstats
            prof = cProfile.Profile()
            prof.runcall(drain, tr, h)
            pstats.Stats(prof, stream=sys.stderr).sort_stats("tottime").print_stats(25)
        else:
            drain(tr, h)
        dt = time.perf_counter() - t
        stats = {"handled": h.messages, "touches": len(h.coord.touches),
                 "journal_ms_per_touch": journal_ms,
                 "journalled": len(j.reports(msg.TOUCH)), "bad_frames": h.bad_frames(),
                 "acks_sent": tr.frames_out}
    assert tr.frames_in == len(fs) and h.messages == len(fs), (tr.frames_in, h.messages)
    return len(fs) / dt, stats


def sustained(ch: str, rate: int, seconds: float) -> dict:
    """A sender thread paces HEARTBEATs at `rate` frames/s (bursts every 10 ms)
    while the host runs its real loop (HostProcess.run, 10 ms ticks); report
    whether every frame was handled and how long the host took to catch up."""
    import threading
    fs = frames(int(rate * seconds))
    with open_bus(f"virtual://{ch}") as tx, CanTransport(open_bus(f"virtual://{ch}")) as tr:
        h = HostProcess(tr, weight=10 ** 6, tick_seconds=0.01)
        h.handle([(r, msg.HELLO, (1, 100, 1)) for r in range(1, ROBOTS + 1)])
        h.messages = 0
        sent_done = threading.Event()
        caught_up: list[float] = []

        def stop() -> bool:
            if sent_done.is_set() and h.messages >= len(fs):
                caught_up.append(time.perf_counter())
                return True
            return False

        th = threading.Thread(target=lambda: h.run(stop=stop, max_ticks=int(seconds * 100) + 1000))
        th.start()
        burst = rate // 100
        t0 = time.perf_counter()
        for i in range(0, len(fs), burst):
            for f in fs[i:i + burst]:
                tx.send(f)
            due = t0 + (i // burst + 1) * 0.01
            delay = due - time.perf_counter()
            if delay > 0:
                time.sleep(delay)
        t_sent = time.perf_counter()
        sent_done.set()
        th.join()
    offered = len(fs) / (t_sent - t0)
    return {"offered_frames_per_s": round(offered), "frames": len(fs),
            "handled": h.messages, "zero_loss": h.messages == len(fs),
            "catch_up_ms_after_last_frame": round((caught_up[0] - t_sent) * 1000, 1)
            if caught_up else None}


def main() -> None:
    fs = frames(N)
    with tempfile.TemporaryDirectory() as d:
        bare_rates, host_rates, keyed_rates = [], [], []
        for k in range(REPEATS):
            bare_rates.append(bare(f"bench-bare-{k}", fs))
            rate, stats = host(f"bench-host-{k}", N, Path(d))
            host_rates.append(rate)
            rate, kstats = host(f"bench-keyed-{k}", N, Path(d), keyed=True)
            keyed_rates.append(rate)
    b, h, hk = max(bare_rates), max(host_rates), max(keyed_rates)
    sus = sustained("bench-sustained", 4 * BUS_MAX, 2.0)
    print(json.dumps({
        "bench": "host_throughput",
        "frames": N, "robots": ROBOTS, "repeats": REPEATS,
        "bare_recv_frames_per_s": round(b),
        "host_frames_per_s": round(h),
        "ratio_host_to_bare": round(h / b, 3),
        "host_keyed_frames_per_s": round(hk),
        "ratio_keyed_host_to_bare": round(hk / b, 3),
        "keyed_zero_loss": kstats["handled"] == N and kstats["bad_frames"] == {},
        "bus_1mbit_max_frames_per_s": BUS_MAX,
        "host_vs_saturated_1mbit_bus": round(h / BUS_MAX, 2),
        "zero_loss": stats["handled"] == N and stats["bad_frames"] == {},
        "touches_journalled": stats["journalled"],
        "journal_ms_per_touch_incl_fsync": round(stats["journal_ms_per_touch"], 3),
        "sustained_4x_bus": sus,
        "host_keyed_vs_saturated_1mbit_bus": round(hk / BUS_MAX, 2),
        # the ratio is the target (the machine is shared: absolute rates vary
        # threefold between runs; the bare loop in the same run is the yardstick)
        "targets_met": hk >= TARGET * b and h >= 4 * BUS_MAX and sus["zero_loss"]
        and stats["bad_frames"] == {} and kstats["bad_frames"] == {},
    }, sort_keys=True))


if __name__ == "__main__":
    main()
