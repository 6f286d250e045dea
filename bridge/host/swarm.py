"""The simulated swarm as bus nodes: the tick engine with every robot behind
one gateway bus and no coordinator of its own (the host runs elsewhere)."""

from __future__ import annotations

import time
from typing import Any, Callable

import can

from bridge.links.canlink import Faults, Gateway
from bridge.links.codec import Message


class SwarmGateway(Gateway):
    """The gateway as the Link an Engine is built with. Its host's end is
    across the bus, so the engine's is empty: SwarmEngine.exchange() neither
    polls nor sends; the bad frames are the robots' side's."""

    def poll(self, timeout: float) -> list[Message]:
        return []

    def send(self, node: int, kind: int, fields: tuple) -> None:
        raise RuntimeError("the swarm's host is across the bus: it sends its own commands")

    def bad_frames(self) -> dict[str, int]:
        return dict(self.decoder.bad.counts)

    def close(self) -> None:
        pass      # the bus is its opener's to close


def swarm_engine(sc: Any, seed: int, bus: can.BusABC, faults_up: Faults | None = None,
                 faults_down: Faults | None = None, keys: dict[int, bytes] | None = None,
                 fresh: Any = None):
    from sim_backend.engine import Engine

    class SwarmEngine(Engine):
        def exchange(self) -> None:
            self.link.flush()
            self.link.drain(None)

        def finished(self) -> bool:
            return self.tick >= self.sc.maxTicks or all_halted(self)

    gw = SwarmGateway(bus, list(range(1, sc.agents + 1)), faults_up, faults_down=faults_down,
                      keys=keys, fresh=fresh)
    return SwarmEngine(sc, seed, link=gw)


def all_halted(engine: Any) -> bool:
    """Every robot is in its behaviour's "halt" state (spec.STATES), the one
    it enters on the host's HALT: with no coordinator of its own, that is how
    the swarm knows the mission ended."""
    halt = engine.behaviour.halt_state
    return all(r.state == halt for r in engine.robots)


def run_swarm(engine: Any, tick_seconds: float, stop: Callable[[], bool] | None = None,
              progress: Callable[[int], None] | None = None,
              clock: Callable[[], float] = time.monotonic) -> dict[str, Any]:
    """Tick the swarm at `tick_seconds` until every robot halted, maxTicks or stop()."""
    next_tick = clock()
    while not engine.finished():
        if stop is not None and stop():
            break
        now = clock()
        if now < next_tick:
            time.sleep(next_tick - now)
        engine.step()
        if progress is not None:
            progress(engine.tick)
        next_tick += tick_seconds
    return swarm_summary(engine)


def swarm_summary(engine: Any) -> dict[str, Any]:
    gw = engine.link
    reports = [[r.node, r.seq] for r in engine.robots if getattr(r, "seq", 0) > 0]
    out = {
        "ticks": engine.tick,
        "robots": len(engine.robots),
        "behaviour": engine.behaviour.name,
        "states": [engine.behaviour.state_name(r.state) for r in engine.robots],
        "reported": reports,
        # a robot that retransmits until ACKed keeps `pending` (the thesis's);
        # a behaviour without one has nothing unacknowledged to show
        "unacked": [r.node for r in engine.robots if getattr(r, "pending", 0)],
        "halted": all_halted(engine),
        "object_cells": sorted(list(c) for c in engine.world.object_cells),
        "frames_sent": gw.sent,
        "frames_received": gw.received,
        "bad_frames": dict(gw.decoder.bad.counts),
    }
    if gw.opener is not None:
        out["locked_out"] = sorted(gw.opener.locked)
        # reports not sent: their robot had taken no host command yet (secoc)
        out["reports_held_back"] = gw.opener.held_back
    for name, f in (("faults_up", gw.faults), ("faults_down", gw.faults_down)):
        if f is not None:
            out[name] = {"dropped": f.dropped, "duplicated": f.duplicated}
    return out
