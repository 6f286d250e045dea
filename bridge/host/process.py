"""The host controller process: coordinator + transport + journal.

One host tick every `tick_seconds` of wall time: frames that arrived since
the last tick are handed to the coordinator as they come (a TOUCH is
journalled before its ACK is queued; a HELLO's node before its ACK), and at
the tick the coordinator's commands go out. Frames from nodes that never
announced themselves with HELLO (and are not in a resumed journal) are
counted as bad frames and never reach the coordinator.
"""

from __future__ import annotations

import logging
import time
from typing import Any, Callable

from bridge.links.codec import UNANNOUNCED, BadFrames, Message
from bridge.host.journal import Journal
from bridge.transport import RobotTransport
from firmware_logic import messages as msg
from firmware_logic.behaviours.thesis.coordinator import Coordinator, Touch

log = logging.getLogger(__name__)

HALT_REPEATS = 10   # HALT is broadcast on this many ticks after delivery (it is not ACKed)


class HostProcess:
    def __init__(self, transport: RobotTransport, weight: int, home_x: int = -15,
                 home_y: int = -15, journal: Journal | None = None,
                 tick_seconds: float = 0.01,
                 on_event: Callable[[str], None] | None = None) -> None:
        self.transport = transport
        self.journal = journal
        self.tick_seconds = tick_seconds
        self.on_event = on_event
        self.bad = BadFrames("host")
        self.coord = Coordinator(weight, home_x, home_y, journal=self._journal_touch)
        self.tick = 0
        self.halts_sent = 0
        self.resumed = 0
        self.messages = 0

    # -- journal ----------------------------------------------------------------

    def resume(self, journal: Journal) -> int:
        """Adopt the nodes and touches of a journal; return the touches restored."""
        for node, (model, power) in journal.nodes().items():
            self.coord.nodes[node] = (model, power)
        touches = journal.touches()
        self.coord.restore(touches)
        self.tick = max(self.tick, journal.last_tick())
        self.resumed = len(touches)
        self._event(f"resumed {len(touches)} touches from {len(self.coord.nodes)} nodes "
                    f"({journal.path}); power {self.coord.power}/{self.coord.weight}")
        return len(touches)

    def _journal_touch(self, t: Touch) -> None:
        if self.journal is not None:
            self.journal.add_touch(t)
        self._event(f"tick {self.tick}: touch from robot {t.node} seq {t.seq} at "
                    f"({t.rx},{t.ry}) segment ({t.sx},{t.sy}); power "
                    f"{self.coord.power + t.power}/{self.coord.weight}")

    def _event(self, text: str) -> None:
        log.info("%s", text)
        if self.on_event is not None:
            self.on_event(text)

    # -- input ----------------------------------------------------------------------

    def handle(self, messages: list[Message]) -> None:
        c = self.coord
        nodes = c.nodes
        on_message = c.on_message
        tick = self.tick
        self.messages += len(messages)
        for node, kind, f in messages:
            if kind == msg.HELLO:
                if node not in c.nodes:
                    if self.journal is not None:
                        self.journal.add_node(node, f[0], f[1])
                    self._event(f"tick {self.tick}: robot {node} announced "
                                f"(model {f[0]}, power {f[1]})")
            elif node not in nodes:
                self.bad.add(UNANNOUNCED, "%s from node %d" % (msg.SCHEMA[kind][0], node))
                continue
            on_message(node, kind, f, tick)

    # -- ticks --------------------------------------------------------------------------

    def step(self) -> None:
        """One host tick: send the coordinator's commands."""
        self.tick += 1
        c = self.coord
        converged = c.converged_tick
        for node, kind, fields in c.tick(self.tick):
            self.transport.send(node, kind, fields)
            if kind == msg.HALT:
                self.halts_sent += 1
        if converged < 0 <= c.converged_tick:
            self._event(f"tick {self.tick}: converged, power {c.power}/{c.weight}; "
                        f"leader robot {c.leader}; transport begins")
        if c.delivered_tick >= 0:
            if c.delivered_tick == self.tick:
                self._event(f"tick {self.tick}: object home; HALT")
            elif self.halts_sent < HALT_REPEATS:
                self.transport.send(msg.HOST, msg.HALT, (0,))
                self.halts_sent += 1

    def done(self) -> bool:
        return self.coord.delivered_tick >= 0 and self.halts_sent >= HALT_REPEATS

    def run(self, stop: Callable[[], bool] | None = None, max_ticks: int | None = None,
            clock: Callable[[], float] = time.monotonic) -> dict[str, Any]:
        """Run until the object is home (and HALT repeated), `stop()` or max_ticks."""
        next_tick = clock() + self.tick_seconds
        start_tick = self.tick
        while not self.done():
            if stop is not None and stop():
                self._event(f"tick {self.tick}: stopped")
                break
            if max_ticks is not None and self.tick - start_tick >= max_ticks:
                self._event(f"tick {self.tick}: gave up after {max_ticks} ticks")
                break
            now = clock()
            while now < next_tick:
                self.handle(self.transport.poll(next_tick - now))
                now = clock()
            self.step()
            next_tick += self.tick_seconds
            if next_tick < now:
                next_tick = now + self.tick_seconds
        return self.summary()

    def bad_frames(self) -> dict[str, int]:
        out = dict(self.transport.bad_frames())
        for k, v in self.bad.counts.items():
            out[k] = out.get(k, 0) + v
        return out

    def summary(self) -> dict[str, Any]:
        c = self.coord
        return {
            "ticks": self.tick,
            "nodes": sorted(c.nodes),
            "touches": [[t.node, t.seq] for t in c.touches],
            "power": c.power / 100,
            "leader": c.leader or None,
            "resumed": self.resumed,
            "duplicates": c.duplicates,
            "converged_tick": c.converged_tick if c.converged_tick >= 0 else None,
            "home_tick": c.delivered_tick if c.delivered_tick >= 0 else None,
            "delivered": c.delivered_tick >= 0,
            "messages": self.messages,
            "bad_frames": self.bad_frames(),
        }
