"""The thesis's world: a bounded arena of patches, one object, a home, and
the potential field robots emit when they hold the object.

Coordinates are NetLogo's: patch centres at integers from -worldSize to
+worldSize, x east, y north, home at (homeX, homeY) = (-15, -15). Grids are
flat Python lists indexed by `idx`, the fastest scalar access in CPython;
the vectorised engine keeps the same grids as numpy arrays.
"""

from __future__ import annotations

import math

from firmware_logic import fixedpoint as fx
from firmware_logic.rng import Rng
from sim_backend import arena, kernel, objects
from sim_backend.kernel import BLUE, FREE, OBSTACLE, YELLOW  # noqa: F401  (the cell values)
from sim_backend.scenario import CHOICES, Scenario


def signal_table(radius: int) -> list[tuple[int, int, int]]:
    """(dx, dy, increment) of Signal (thesis eq. 3): round(10 / (1 + d)) on
    every patch within sigRadius of the source; NetLogo rounds halves up."""
    out = []
    for ddy in range(-radius, radius + 1):
        for ddx in range(-radius, radius + 1):
            d2 = ddx * ddx + ddy * ddy
            if d2 <= radius * radius:
                v = math.floor(10.0 / (1.0 + math.sqrt(d2)) + 0.5)
                if v:
                    out.append((ddx, ddy, v))
    return out


def multi_step(sc: Scenario) -> tuple[int, int]:
    """(state code, extra steps): under sequential activation a robot whose
    turn starts in that state of the behaviour takes 1 + extra FSM steps per
    go iteration, as the behaviour declares in its __init__.MULTI_STEP
    ((state name, parameter name)); (-1, 0) when it declares none."""
    from sim_backend import registry
    b = registry.load(sc.behaviour)
    decl = getattr(b.package, "MULTI_STEP", None)
    if decl is None:
        return -1, 0
    return b.spec.STATES.index(decl[0]), int(getattr(sc, decl[1]))


class World:
    def __init__(self, sc: Scenario, seed: int):
        self.sc = sc
        self.seed = seed
        self.w = sc.worldSize
        self.n = 2 * sc.worldSize + 1
        size = self.n * self.n
        self.obj = [FREE] * size
        self.owner = [0] * size          # node holding a BLUE patch
        self.field = [0] * size
        self.occ = [0] * size            # robots per patch at the tick's start
        self.stamp = [-1] * size         # tick in which a patch was last entered
        self.table = signal_table(sc.sigRadius)
        self.tdx = [t[0] for t in self.table]
        self.tdy = [t[1] for t in self.table]
        self.tv = [t[2] for t in self.table]
        setup = Rng(seed, 0)             # the observer's stream, as in setup
        # CreateWorld: objx, objy = random 10 (the target's, when not given)
        pieces = sc.pieces()
        if pieces:
            target = pieces[0]
            self.obj_x = target.at[0] if target.at is not None else setup.below(10)
            self.obj_y = target.at[1] if target.at is not None else setup.below(10)
            self.object_cells = target.placed(self.obj_x, self.obj_y)   # the carried object
        else:                            # object = "none": an empty arena
            self.obj_x = self.obj_y = 0
            self.object_cells = []
        # where the carried object stood at the start: its own frame, the one
        # the host stores touches in (measures.shape_iou, perception)
        self.start_cells = list(self.object_cells)
        # the other objects (decoys) and the obstacles never move
        self.decoy_cells = [c for p in pieces[1:] for c in p.placed(*p.at)]
        self.obstacle_cells = [c for p in sc.obstacles for c in p.placed(*p.at)]
        for x, y in self.object_cells + self.decoy_cells:
            self.obj[self.idx(x, y)] = YELLOW
        for x, y in self.obstacle_cells:
            self.obj[self.idx(x, y)] = OBSTACLE
        # the arena's rules (kernel.DYNAMIC, YIELD flags; 0 the thesis's)
        self.rules = (kernel.DYNAMIC if sc.field == arena.FIELD_MODES[1] else 0) | \
            (kernel.YIELD if sc.crowd == arena.CROWD_MODES[1] else 0) | \
            (kernel.WRAP if sc.wrap else 0) | \
            (kernel.SELF_COUNTS if sc.probeSelf == "netlogo" else 0) | \
            (kernel.TOWARDS if sc.uphillHeading == "netlogo" else 0)
        self.xs: list[int] = []
        self.ys: list[int] = []
        if sc.starts == "netlogo":
            self._netlogo_starts(sc, seed, setup)
        else:
            self._redrawn_starts(sc, setup)
        # every robot's intents and holdings, as the kernel reads them
        a = sc.agents
        self.held = [-1] * a             # held cell, -1: none
        self.mv_on = [0] * a             # a forward() this tick, of mv_step along mv_h
        self.mv_h = [0] * a
        self.mv_step = [0] * a
        self.claim = [-1] * a            # cell claimed this tick
        self.beacon_set = [-1] * a       # -1: no beacon() call this tick
        self.beacon_on = [0] * a         # field source on, centred on (bsx, bsy)
        self.bsx = [0] * a
        self.bsy = [0] * a
        self.carry_on = [0] * a          # a carry() asked and not yet consumed
        self.carry_dx = [0] * a
        self.carry_dy = [0] * a
        # the NetLogo options the kernel reads (scenario.CHOICES; index 0 the default)
        self.sigmode = CHOICES["signalMode"].index(sc.signalMode)
        self.ties = CHOICES["uphillTies"].index(sc.uphillTies)
        self.tie = [kernel.tie_seed(seed, node) for node in range(1, a + 1)]
        # activation (kernel.SYNC, SEQUENTIAL): with SEQUENTIAL the engine draws
        # an order every go iteration and applies each robot's actions at once
        self.act = CHOICES["activation"].index(sc.activation)
        self.order = list(range(a))
        self.order_state = [kernel.order_seed(seed)]
        self.field_state, self.extra_steps = multi_step(sc)
        self.recount()

    def _redrawn_starts(self, sc: Scenario, setup: Rng) -> None:
        """Our CreateSwarm: each robot walks `random max-pxcor` from the origin
        along a `random 360` heading; a start on the object or on another
        robot is redrawn, and the robot draws its own heading afresh."""
        taken = set()
        while len(self.xs) < sc.agents:
            h = setup.below(360)
            dist = setup.below(self.w) * fx.ONE
            x = fx.dx(h, dist)
            y = fx.dy(h, dist)
            p = (fx.patch(x), fx.patch(y))
            if not self.inside(*p) or self.obj[self.idx(*p)] != FREE or p in taken:
                continue
            taken.add(p)
            self.xs.append(x)
            self.ys.append(y)

    def _netlogo_starts(self, sc: Scenario, seed: int, setup: Rng) -> None:
        """CreateSwarm as Appendix A writes it: `fd random max-pxcor` from the
        origin along the robot's own heading, which it keeps; robots may share
        a patch or stand on the object (NetLogo turtles do). The heading is
        the first draw of the robot's RNG, the one a thesis Robot takes as
        its starting heading (robot.py, __init__)."""
        for node in range(1, sc.agents + 1):
            h = Rng(seed, node).below(360)
            dist = setup.below(self.w) * fx.ONE
            self.xs.append(fx.dx(h, dist))
            self.ys.append(fx.dy(h, dist))

    def cell_arrays(self) -> tuple[list[int], list[int], list[int], list[int]]:
        """The object's cells as the kernel moves them: xs, ys and scratch."""
        m = len(self.object_cells)
        return [c[0] for c in self.object_cells], [c[1] for c in self.object_cells], \
            [0] * m, [0] * m

    def apply(self, tick: int) -> None:
        """Apply the robots' intents of this tick (sim_backend/kernel.py)."""
        cx, cy, cv, cw = self.cell_arrays()
        kernel.apply_tick(self.obj, self.owner, self.field, self.occ, self.stamp, 0, self.w,
                          self.n, self.tdx, self.tdy, self.tv, 0, len(self.tv), self.xs,
                          self.ys, 0, len(self.xs), self.held, self.mv_on, self.mv_h,
                          self.mv_step, self.claim, self.beacon_set, self.beacon_on,
                          self.bsx, self.bsy, self.carry_on, self.carry_dx, self.carry_dy,
                          cx, cy, cv, cw, 0, len(cx), tick, self.sigmode, self.sc.sigRadius,
                          self.rules)
        self.object_cells = list(zip(cx, cy))

    # -- sequential activation (kernel.SEQUENTIAL) ------------------------------

    def draw_order(self) -> list[int]:
        """This go iteration's order of robot indices (kernel.draw_order)."""
        kernel.draw_order(self.order, 0, len(self.xs), self.order_state, 0)
        return list(self.order)

    def apply_robot(self, i: int) -> None:
        """Robot i's claim and move of its last step, at once."""
        kernel.apply_robot(self.obj, self.owner, self.occ, 0, self.w, self.n, self.xs,
                           self.ys, 0, i, self.held, self.mv_on, self.mv_h, self.mv_step,
                           self.claim, self.rules)

    def end_iteration(self, tick: int) -> None:
        """Beacons, the carried group and occupancy after every robot's turn."""
        cx, cy, cv, cw = self.cell_arrays()
        kernel.end_iteration(self.obj, self.owner, self.field, self.occ, self.stamp, 0,
                             self.w, self.n, self.tdx, self.tdy, self.tv, 0, len(self.tv),
                             self.xs, self.ys, 0, len(self.xs), self.held, self.beacon_set,
                             self.beacon_on, self.bsx, self.bsy, self.carry_on,
                             self.carry_dx, self.carry_dy, cx, cy, cv, cw, 0, len(cx), tick,
                             self.sigmode, self.sc.sigRadius, self.order, self.rules)
        self.object_cells = list(zip(cx, cy))

    def idx(self, px: int, py: int) -> int:
        return (py + self.w) * self.n + (px + self.w)

    def inside(self, px: int, py: int) -> bool:
        return -self.w <= px <= self.w and -self.w <= py <= self.w

    def recount(self) -> None:
        kernel.recount(self.occ, 0, self.w, self.n, self.xs, self.ys, 0, len(self.xs))

    def uphill(self, i: int) -> int:
        """kernel.uphill for robot index i."""
        return kernel.uphill(self.field, 0, self.w, self.n, self.xs[i], self.ys[i],
                             self.ties, self.tie, i, self.rules)

    def signal(self, px: int, py: int, sign: int = 1) -> None:
        """Add (or, sign=-1, remove) one beacon's field centred on a patch."""
        kernel.signal(self.field, 0, self.w, self.n, self.tdx, self.tdy, self.tv, 0,
                      len(self.tv), px, py, sign, self.rules)
