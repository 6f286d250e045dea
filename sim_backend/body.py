"""A simulated robot body: the HAL of firmware_logic/hal.py over the World.

Sensing reads the world as it stood at the start of the tick; acting only
records an intent, which the engine applies after every robot has decided
(docs/tick-semantics.md).
"""

from __future__ import annotations

from firmware_logic import messages as msg
from firmware_logic import hal
from firmware_logic.hal import Hal
from sim_backend import faults, kernel
from sim_backend.world import World


class SimBody(Hal):
    """Robot `index` (node `node`) of a World; the rules are sim_backend/kernel.py."""

    def __init__(self, world: World, index: int, node: int, link) -> None:
        self.world = world
        self.i = index
        self.node = node
        self.link = link
        self.tape = None           # optional list receiving (query, arg, value)
        self.acts = None           # optional list receiving (action, a, b)
        self.sent = None           # optional list receiving (node, kind, fields) sent
        # faults (sim_backend/faults.py): this robot's share of the run's plan
        self.faulty = faults.active(world.sc)
        if self.faulty:
            die, s0, s1, flags = faults.plan(world.sc, world.seed)
            self.die, self.s0, self.s1, self.flags = die[index], s0[index], s1[index], flags[index]
            self.fseed, self.miss, self.ghost, self.noise = faults.per_run(world.sc, world.seed)
        self.t = -1                # the tick (reset_intents starts each one)
        self.k = 0                 # fault draws this tick
        self.reset_intents()

    def reset_intents(self) -> None:
        w = self.world
        w.mv_on[self.i] = 0
        w.claim[self.i] = -1
        w.beacon_set[self.i] = -1
        self.t += 1
        self.k = 0
        if self.faulty and self.t == self.die:
            # it goes limp: its beacon dies and its grip lets go
            w.beacon_set[self.i] = 0
            faults.release(w.obj, w.owner, 0, w.held, self.i)

    # -- faults ------------------------------------------------------------

    def dead(self) -> bool:
        return self.faulty and self.t >= self.die

    def _draw(self) -> int:
        self.k += 1
        return faults.draw(self.fseed, self.i, self.t, self.k)

    def _sensed_field(self, v: int) -> int:
        if self.flags & (faults.IGNORE_FIELD | faults.RANDOM):
            return 0
        if self.noise:
            v += self._draw() % (2 * self.noise + 1) - self.noise
        return v if v > 0 else 0

    @property
    def held(self) -> int:
        """Cell of the segment this robot holds, -1 if none."""
        return self.world.held[self.i]

    # -- sensing ----------------------------------------------------------

    def x(self) -> int:
        return self.world.xs[self.i]

    def y(self) -> int:
        return self.world.ys[self.i]

    def probe(self, heading: int) -> int:
        w = self.world
        r = kernel.probe(w.obj, w.occ, 0, w.w, w.n, w.xs[self.i], w.ys[self.i], heading,
                         w.rules)
        if self.faulty:
            if r == hal.OBJECT and self.flags & faults.RANDOM:
                r = hal.ROBOT
            elif r == hal.OBJECT and self.miss and self._draw() < self.miss:
                r = hal.NOTHING
            elif r == hal.NOTHING and self.ghost and self._draw() < self.ghost:
                r = hal.OBJECT
        if self.tape is not None:
            self.tape.append((hal.PROBE, heading, r))
        return r

    def field_ahead(self, heading: int) -> int:
        w = self.world
        v = kernel.field_ahead(w.field, 0, w.w, w.n, w.xs[self.i], w.ys[self.i], heading,
                               w.rules)
        if self.faulty:
            v = self._sensed_field(v)
        if self.tape is not None:
            self.tape.append((hal.FIELD_AHEAD, heading, v))
        return v

    def field_here(self) -> int:
        w = self.world
        v = kernel.field_here(w.field, 0, w.w, w.n, w.xs[self.i], w.ys[self.i])
        if self.faulty:
            v = self._sensed_field(v)
        if self.tape is not None:
            self.tape.append((hal.FIELD_HERE, 0, v))
        return v

    def uphill(self) -> int:
        w = self.world
        out = w.uphill(self.i)
        if self.faulty and self.flags & (faults.IGNORE_FIELD | faults.RANDOM):
            out = -1
        if self.tape is not None:
            self.tape.append((hal.UPHILL, 0, out))
        return out

    def holding(self) -> int:
        r = kernel.holding(self.world.owner, 0, self.world.held[self.i], self.node)
        if self.tape is not None:
            self.tape.append((hal.HOLDING, 0, r))
        return r

    # -- acting (intents, applied by World.apply) ----------------------------------

    # the tapes (self.acts, self.sent) take the firmware's decision before
    # any fault filter: a recording holds what the firmware decided, the
    # faults only what became of it (bridge/record/recorder.py)

    def forward(self, heading: int, step: int) -> None:
        if self.acts is not None:
            self.acts.append((hal.FORWARD, heading, step))
        if self.faulty and (self.dead() or self.s0 <= self.t < self.s1):
            return
        w = self.world
        w.mv_on[self.i] = 1
        w.mv_h[self.i] = heading
        w.mv_step[self.i] = step

    def claim(self, heading: int) -> None:
        if self.acts is not None:
            self.acts.append((hal.CLAIM, heading, 0))
        if self.faulty and self.dead():
            return
        w = self.world
        w.claim[self.i] = kernel.ahead_cell(w.w, w.n, w.xs[self.i], w.ys[self.i], heading,
                                            w.rules)

    def carry(self, dx: int, dy: int) -> None:
        if self.acts is not None:
            self.acts.append((hal.CARRY, dx, dy))
        if self.faulty and self.dead():
            return
        w = self.world
        w.carry_on[self.i] = 1
        w.carry_dx[self.i] = dx
        w.carry_dy[self.i] = dy

    def beacon(self, on: int) -> None:
        if self.acts is not None:
            self.acts.append((hal.BEACON, on, 0))
        if self.faulty and self.dead():
            return
        self.world.beacon_set[self.i] = on

    # -- messages ------------------------------------------------------------------

    def send(self, kind: int, a0: int, a1: int, a2: int, a3: int, a4: int, a5: int) -> None:
        n = len(msg.fields(kind))
        fields = (a0, a1, a2, a3, a4, a5)[:n]
        if self.sent is not None:
            self.sent.append((self.node, kind, fields))
        if self.faulty and self.dead():
            return
        self.link.robot_send(self.node, kind, fields)

    def recv(self, buf: list) -> int:
        m = self.link.robot_recv(self.node)
        while m is not None and self.faulty and (
                self.dead() or (self.flags & faults.IGNORE_HOST
                                and m[0] in (msg.TRANSPORT, msg.HALT))):
            m = self.link.robot_recv(self.node)     # lost on a dead or defiant robot
        if m is None:
            if self.tape is not None:
                self.tape.append((hal.RECV, 0, 0))
            return 0
        kind, fields = m
        for j, v in enumerate(fields):
            buf[j] = v
        if self.tape is not None:
            self.tape.append((hal.RECV, kind, tuple(fields)))
        return kind
