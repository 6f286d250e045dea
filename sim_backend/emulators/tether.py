"""The sim world as the body of tethered robots (firmware_logic/board.py).

`TetherTransport` wraps the host's end of any link (sim_backend/link.py
HostEnd; a SerialTransport per board, say) and is one itself: it answers
the SENSOR queries and applies the ACTION intents of the tethered nodes
from a sim Engine's world, and passes every other message (HELLO, TOUCH,
HEARTBEAT) through to the host unchanged. Robots of the
engine that are not tethered stand still (they are obstacles).

A tick of a tethered robot ends when it sends ACTION END; the world then
applies its intents with the engine's tick rule (claims, beacons, carried
group, moves) and answers END. Requests repeated by the board (a lost
answer) are answered again and never applied twice. A board's ACTION STOP (its loop
has ended) is recorded in `stopped`; wait on that, not on silence, before
using the port for anything else (the REPL).
"""

from __future__ import annotations

import logging
from types import TracebackType
from typing import Any, Protocol

from firmware_logic import board, hal
from firmware_logic import messages as msg
from sim_backend.link import HostEnd, Message

log = logging.getLogger(__name__)


class Stepper(Protocol):
    """What the tether serves the boards from: an engine's bodies and its
    rule that applies their intents (sim_backend.engine.Engine, or a mixed
    mission's link, bridge/mission.py MixedLink, which applies the boards' only)."""

    @property
    def bodies(self) -> list[Any]: ...

    def _apply(self) -> None: ...


class TetherTransport:
    def __init__(self, inner: HostEnd, engine: Stepper, nodes: list[int]) -> None:
        self.inner = inner
        self.engine = engine
        self.bodies = {b.node: b for b in engine.bodies if b.node in nodes}
        unknown = set(nodes) - set(self.bodies)
        if unknown:
            raise ValueError("nodes %s are not robots of the scenario (1..%d)"
                             % (sorted(unknown), len(engine.bodies)))
        self.last_end: dict[int, int] = {}        # node -> last applied robot tick
        self.answered = 0
        self.applied_ticks = 0
        self.stopped: dict[int, int] = {}         # node -> robot tick its loop ended at

    def __enter__(self) -> "TetherTransport":
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def _sense(self, body, query: int, arg: int) -> int:
        if query == hal.PROBE:
            return body.probe(arg)
        if query == hal.FIELD_AHEAD:
            return body.field_ahead(arg)
        if query == hal.FIELD_HERE:
            return body.field_here()
        if query == hal.UPHILL:
            return body.uphill()
        if query == hal.HOLDING:
            return body.holding()
        if query == hal.POS_X:
            return body.x()
        if query == hal.POS_Y:
            return body.y()
        raise ValueError("unknown sensor query %d" % query)

    def _serve(self, node: int, kind: int, f: tuple) -> None:
        body = self.bodies[node]
        tick, index, code, a, b = f
        if kind == msg.SENSOR:
            try:
                v = self._sense(body, code, a)
            except ValueError as err:
                log.warning("node %d: %s", node, err)
                return
            self.inner.send(node, msg.SENSOR, (tick, index, code, a, v))
            self.answered += 1
            return
        if board.is_stop(kind, f):
            # the board's loop has ended (board.run): it reads no more
            if node not in self.stopped:
                log.info("node %d: its loop ended at tick %d", node, tick)
            self.stopped[node] = tick
            return
        if code == board.A_END:
            if self.last_end.get(node) != tick:
                self.last_end[node] = tick
                self.engine._apply()
                for bd in self.engine.bodies:
                    bd.reset_intents()
                self.applied_ticks += 1
            self.inner.send(node, msg.ACTION, (tick, index, board.A_END, 0, 0))
        elif self.last_end.get(node) == tick:
            return            # an action repeated after its tick was applied
        elif code == hal.FORWARD:
            body.forward(a, b)
        elif code == hal.CLAIM:
            body.claim(a)
        elif code == hal.CARRY:
            body.carry(a, b)
        elif code == hal.BEACON:
            body.beacon(a)

    def poll(self, timeout: float) -> list[Message]:
        out: list[Message] = []
        for node, kind, f in self.inner.poll(timeout):
            if kind in (msg.SENSOR, msg.ACTION) and node in self.bodies:
                self._serve(node, kind, f)
            else:
                out.append((node, kind, f))
        return out

    def send(self, node: int, kind: int, fields: tuple) -> None:
        self.inner.send(node, kind, fields)

    def bad_frames(self) -> dict[str, int]:
        return self.inner.bad_frames()

    def close(self) -> None:
        self.inner.close()
