"""A simulated robot body: the HAL of firmware_logic/hal.py over the World.

Sensing reads the world as it stood at the start of the tick; acting only
records an intent, which the engine applies after every robot has decided
(docs/tick-semantics.md).
"""

from __future__ import annotations

from firmware_logic import fixedpoint as fx
from firmware_logic import messages as msg
from firmware_logic.hal import Hal
from firmware_logic.behaviours.thesis.robot import CLAIMED, NOTHING, OBJECT, ROBOT, WALL
from sim_backend.world import BLUE, YELLOW, World

UPHILL = ((0, 0, 1), (45, 1, 1), (90, 1, 0), (135, 1, -1),
          (180, 0, -1), (225, -1, -1), (270, -1, 0), (315, -1, 1))


class SimBody(Hal):
    def __init__(self, world: World, index: int, node: int, link) -> None:
        self.world = world
        self.i = index
        self.node = node
        self.link = link
        self.held = -1             # flat index of the held patch
        self.carry_intent: tuple[int, int] | None = None  # kept until the group moves
        self.tape = None           # optional list receiving (query, arg, value)
        self.acts = None           # optional list receiving (action, a, b)
        self.reset_intents()

    def reset_intents(self) -> None:
        self.move: tuple[int, int] | None = None
        self.claim_cell = -1
        self.beacon_set = -1

    # -- sensing ----------------------------------------------------------

    def x(self) -> int:
        return self.world.xs[self.i]

    def y(self) -> int:
        return self.world.ys[self.i]

    def _ahead(self, h: int) -> tuple[int, int]:
        return (fx.patch(self.world.xs[self.i] + fx.dx(h, fx.ONE)),
                fx.patch(self.world.ys[self.i] + fx.dy(h, fx.ONE)))

    def probe(self, heading: int) -> int:
        w = self.world
        px, py = self._ahead(heading)
        if not w.inside(px, py):
            r = WALL
        else:
            k = w.idx(px, py)
            o = w.obj[k]
            if o == YELLOW:
                r = OBJECT
            elif o == BLUE:
                r = CLAIMED
            else:
                n = w.occ[k]
                if px == fx.patch(w.xs[self.i]) and py == fx.patch(w.ys[self.i]):
                    n -= 1
                r = ROBOT if n > 0 else NOTHING
        if self.tape is not None:
            self.tape.append((1, heading, r))
        return r

    def field_ahead(self, heading: int) -> int:
        w = self.world
        px, py = self._ahead(heading)
        v = w.field[w.idx(px, py)] if w.inside(px, py) else 0
        if self.tape is not None:
            self.tape.append((2, heading, v))
        return v

    def field_here(self) -> int:
        w = self.world
        v = w.field[w.idx(fx.patch(w.xs[self.i]), fx.patch(w.ys[self.i]))]
        if self.tape is not None:
            self.tape.append((3, 0, v))
        return v

    def uphill(self) -> int:
        w = self.world
        px = fx.patch(w.xs[self.i])
        py = fx.patch(w.ys[self.i])
        best = w.field[w.idx(px, py)]
        out = -1
        for h, ddx, ddy in UPHILL:
            if w.inside(px + ddx, py + ddy):
                v = w.field[w.idx(px + ddx, py + ddy)]
                if v > best:
                    best = v
                    out = h
        if self.tape is not None:
            self.tape.append((4, 0, out))
        return out

    def holding(self) -> int:
        r = 1 if self.held >= 0 and self.world.owner[self.held] == self.node else 0
        if self.tape is not None:
            self.tape.append((5, 0, r))
        return r

    # -- acting (intents) ------------------------------------------------------

    def forward(self, heading: int, step: int) -> None:
        self.move = (heading, step)
        if self.acts is not None:
            self.acts.append((1, heading, step))

    def claim(self, heading: int) -> None:
        px, py = self._ahead(heading)
        self.claim_cell = self.world.idx(px, py)
        if self.acts is not None:
            self.acts.append((2, heading, 0))

    def carry(self, dx: int, dy: int) -> None:
        self.carry_intent = (dx, dy)
        if self.acts is not None:
            self.acts.append((3, dx, dy))

    def beacon(self, on: int) -> None:
        self.beacon_set = on
        if self.acts is not None:
            self.acts.append((4, on, 0))

    # -- messages ------------------------------------------------------------------

    def send(self, kind: int, a0: int, a1: int, a2: int, a3: int, a4: int, a5: int) -> None:
        n = len(msg.fields(kind))
        self.link.robot_send(self.node, kind, (a0, a1, a2, a3, a4, a5)[:n])

    def recv(self, buf: list) -> int:
        m = self.link.robot_recv(self.node)
        if m is None:
            if self.tape is not None:
                self.tape.append((6, 0, 0))
            return 0
        kind, fields = m
        for j, v in enumerate(fields):
            buf[j] = v
        if self.tape is not None:
            self.tape.append((6, kind, tuple(fields)))
        return kind
