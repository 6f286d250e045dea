"""A forger on the bus during a whole mission: before every robot tick it
sends every host command it can make (plain HALT, ACK and TRANSPORT to every
robot, broadcast HALT, commands sealed with another swarm's keys) and replays
every genuine host frame it has heard. Without keys the robots obey it; with
`--keys` they drop all of it (counted by kind) and the mission delivers with
every touch exactly once. Host and swarm on one simulated clock (Lockstep)."""

from __future__ import annotations

import can

from bridge.host.process import HostProcess
from bridge.host.swarm import swarm_engine, swarm_summary
from bridge.host.transport import CanTransport
from bridge.links import open_bus, secoc
from bridge.links.canlink import private_channel
from bridge.links.codec import encode
from firmware_logic import messages as msg
from hil_tests.test_can_mission import TICK, Lockstep, SimClock
from sim_backend import scenario


class Draining(Lockstep):
    """Lockstep that reads every frame waiting before the clock moves: on a
    simulated clock no time passes while the host reads, so a host on a real
    clock would read them all within its tick (a poll(0) reads one frame, and
    the forger's frames would otherwise queue up without end)."""

    def poll(self, timeout):
        got = []
        while True:
            before = self.inner.frames_in
            got += self.inner.poll(0.0)
            if self.inner.frames_in == before:
                break
        return got or super().poll(timeout)


class Forger:
    def __init__(self, bus: can.BusABC, nodes: list[int]) -> None:
        self.bus = bus
        self.nodes = nodes
        self.alien = secoc.Sealer({n: bytes([0xA5]) * 16 for n in nodes})
        self.heard: list[can.Message] = []
        self.sent = 0

    def strike(self) -> None:
        while (f := self.bus.recv(0.0)) is not None:
            kind, node = msg.split_id(f.arbitration_id)
            if kind in secoc.down_kinds():
                self.heard.append(f)
        frames = [encode(0, msg.HALT, (0,))]
        for n in self.nodes:
            frames += [encode(n, msg.HALT, (0,)), encode(n, msg.ACK, (1,)),
                       encode(n, msg.TRANSPORT, (1, 1, 1))]
            frames += self.alien.seal(encode(n, msg.HALT, (0,)))
        frames += self.heard[-40:]          # replay what the host said lately
        for f in frames:
            self.bus.send(f)
        self.sent += len(frames)


def forged_mission(keys: dict[int, bytes] | None, max_ticks: int = 6000) -> dict:
    sc = scenario.load("default")
    url = f"virtual://{private_channel('auth')}"
    clock = SimClock()
    with open_bus(url) as rb, open_bus(url) as fb:
        engine = swarm_engine(sc, 1, rb, keys=keys)
        forger = Forger(fb, list(range(1, sc.agents + 1)))
        step = engine.step

        def forged_step() -> None:
            forger.strike()
            step()
        engine.step = forged_step
        sealer = secoc.Sealer(keys) if keys is not None else None
        host = HostProcess(Draining(CanTransport(open_bus(url), sealer=sealer), engine, clock),
                           sc.weight_centi, sc.homeX, sc.homeY, tick_seconds=TICK)
        with host.transport:
            out = host.run(max_ticks=max_ticks, clock=clock)
        opener = engine.link.opener
        return {"host": out, "robots": swarm_summary(engine), "forged": forger.sent,
                "failed": opener.failed if opener is not None else {},
                "halt": engine.behaviour.halt_state,
                "states": [r.state for r in engine.robots]}


def test_without_keys_a_forger_stops_the_mission():
    out = forged_mission(None, max_ticks=400)
    assert not out["host"]["delivered"]
    assert set(out["states"]) == {out["halt"]}       # every robot obeyed the forged HALT


def test_with_keys_every_forged_command_is_dropped_and_the_mission_delivers_exactly_once():
    keys = {n: bytes([n, 7]) * 8 for n in range(1, 21)}
    out = forged_mission(keys)
    h, r = out["host"], out["robots"]
    assert h["delivered"], h
    touches = [tuple(t) for t in h["touches"]]
    assert len(touches) == len(set(touches)) and h["power"] == len(touches)
    assert {tuple(t) for t in r["reported"]} == set(touches)
    assert r["unacked"] == [] and r["halted"]
    bad = r["bad_frames"]
    assert set(bad) == {secoc.UNAUTHENTICATED, secoc.BAD_MAC, secoc.STALE}, bad
    # everything the forger sent was dropped: plain, alien-keyed and replayed
    assert sum(bad.values()) == out["forged"]
    # counted per robot; this forger stays below the brute-force lockout
    assert r["locked_out"] == [] and 0 < max(out["failed"].values()) < secoc.LOCKOUT
    # the host sees the forger's host commands as what they are
    assert h["bad_frames"].get("wrong direction", 0) > 0


def test_host_and_robots_processes_with_keys_deliver_and_drop_nothing_genuine(tmp_path):
    """`touchswarm keys new`, then `robots --keys` behind an SLCAN face on a pty
    and `host --keys` on it: every host command sealed and opened across two
    processes (no genuine frame refused), the host's counters persisted."""
    import json
    import subprocess

    from hil_tests.test_can_host_restart import EXE, SC, lines_of, stop_all, wait_for
    keys = tmp_path / "keys.toml"
    subprocess.run([EXE, "keys", "new", "--nodes", "20", "--out", str(keys)], check=True,
                   capture_output=True)
    adapter = tmp_path / "adapter"
    robots = subprocess.Popen([EXE, "robots", "--bus", f"slcan-pty://{adapter}", *SC,
                               "--keys", str(keys), "--tick-ms", "4", "--linger-ms", "1500",
                               "--json"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                              text=True)
    procs = [robots]
    try:
        wait_for(lines_of(robots.stderr), lambda s: "authenticated" in s[-1], 60)
        host = subprocess.Popen([EXE, "host", "--bus", f"slcan://{adapter}?settle_ms=0", *SC,
                                 "--keys", str(keys), "--tick-ms", "4", "--json"],
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        procs.append(host)
        out, err = host.communicate(timeout=300)
        assert host.returncode == 0, err
        h = json.loads(out.strip().splitlines()[-1])
        rout, _ = robots.communicate(timeout=120)
        r = json.loads(rout.strip().splitlines()[-1])
    finally:
        stop_all(procs)
    assert h["delivered"] and r["halted"]
    assert r["bad_frames"] == {}            # every sealed command opened
    # and every sealed report: the host dropped none of the robots' frames
    assert not [k for k in h["bad_frames"] if "MAC" in k or "report" in k], h["bad_frames"]
    assert {tuple(t) for t in r["reported"]} == {tuple(t) for t in h["touches"]}
    fv = json.loads((tmp_path / "keys.toml.fv.json").read_text())
    assert set(fv) == {str(n) for n in range(1, 21)}     # HALT went to every robot
    # the robots keep their floor too (a next mission refuses this one's frames)
    floor = json.loads((tmp_path / "keys.toml.robots.fv.json").read_text())
    assert set(floor) == set(fv) and min(floor.values()) > 0
