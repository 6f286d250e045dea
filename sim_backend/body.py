"""A simulated robot body: the HAL of firmware_logic/hal.py over the World.

Sensing reads the world as it stood at the start of the tick; acting only
records an intent, which the engine applies after every robot has decided
(docs/tick-semantics.md).
"""

from __future__ import annotations

from firmware_logic import messages as msg
from firmware_logic import hal
from firmware_logic.hal import Hal
from sim_backend import kernel
from sim_backend.world import World


class SimBody(Hal):
    """Robot `index` (node `node`) of a World: the HAL over the kernel's state
    (sim_backend/kernel.py holds the rules, faults included); this adds the
    tapes and the link."""

    def __init__(self, world: World, index: int, node: int, link) -> None:
        self.world = world
        self.i = index
        # the kernel's state, which the World never replaces, held here: a
        # probe is most of a reference tick, and each lookup costs in CPython
        self.grid = world.grid
        self.run = world.run
        self.rb = world.rb
        self.xs = world.xs
        self.ys = world.ys
        self.node = node
        self.link = link
        self.tape = None           # optional list receiving (query, arg, value)
        self.acts = None           # optional list receiving (action, a, b)
        self.sent = None           # optional list receiving (node, kind, fields) sent
        # whether the run injects faults (sim_backend/faults.py): when not, no
        # fault rule is asked
        self.faulty = world.run.faulty[0] == 1
        self.reset_intents()

    def reset_intents(self) -> None:
        """A new turn: no intents yet (kernel.start_turn, which lets a robot
        whose death tick it is go limp)."""
        kernel.start_turn(self.grid, self.rb, self.run, 0, self.i)

    # -- faults ------------------------------------------------------------

    def dead(self) -> bool:
        return self.faulty and kernel.dead(self.rb, self.run, 0, self.i) == 1

    @property
    def held(self) -> int:
        """Cell of the segment this robot holds, -1 if none."""
        return self.world.held[self.i]

    # -- sensing ----------------------------------------------------------

    def x(self) -> int:
        return self.xs[self.i]

    def y(self) -> int:
        return self.ys[self.i]

    def probe(self, heading: int) -> int:
        i = self.i
        r = kernel.probe(self.grid, self.run, 0, self.xs[i], self.ys[i], heading)
        if self.faulty:
            r = kernel.sensed_probe(self.rb, self.run, 0, i, r)
        if self.tape is not None:
            self.tape.append((hal.PROBE, heading, r))
        return r

    def field_ahead(self, heading: int) -> int:
        i = self.i
        v = kernel.field_ahead(self.grid, self.run, 0, self.xs[i], self.ys[i], heading)
        if self.faulty:
            v = kernel.sensed_field(self.rb, self.run, 0, i, v)
        if self.tape is not None:
            self.tape.append((hal.FIELD_AHEAD, heading, v))
        return v

    def field_here(self) -> int:
        i = self.i
        v = kernel.field_here(self.grid, self.run, 0, self.xs[i], self.ys[i])
        if self.faulty:
            v = kernel.sensed_field(self.rb, self.run, 0, i, v)
        if self.tape is not None:
            self.tape.append((hal.FIELD_HERE, 0, v))
        return v

    def uphill(self) -> int:
        out = kernel.uphill(self.grid, self.rb, self.run, 0, self.i)
        if self.faulty:
            out = kernel.sensed_uphill(self.rb, self.run, 0, self.i, out)
        if self.tape is not None:
            self.tape.append((hal.UPHILL, 0, out))
        return out

    def holding(self) -> int:
        r = kernel.holding(self.grid, self.rb, self.run, 0, self.i)
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
        if self.faulty and kernel.stuck(self.rb, self.run, 0, self.i) == 1:
            return
        rb = self.rb
        i = self.i
        rb.mv_on[i] = 1
        rb.mv_h[i] = heading
        rb.mv_step[i] = step

    def claim(self, heading: int) -> None:
        if self.acts is not None:
            self.acts.append((hal.CLAIM, heading, 0))
        if self.faulty and self.dead():
            return
        self.rb.claim[self.i] = kernel.claim_cell(self.rb, self.run, 0, self.i, heading)

    def carry(self, dx: int, dy: int) -> None:
        if self.acts is not None:
            self.acts.append((hal.CARRY, dx, dy))
        if self.faulty and self.dead():
            return
        rb = self.rb
        rb.carry_on[self.i] = 1
        rb.carry_dx[self.i] = dx
        rb.carry_dy[self.i] = dy

    def beacon(self, on: int) -> None:
        if self.acts is not None:
            self.acts.append((hal.BEACON, on, 0))
        if self.faulty and self.dead():
            return
        self.rb.beacon_set[self.i] = on

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
        while m is not None and self.faulty and kernel.drops(self.rb, self.run, 0, self.i, m[0]):
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
