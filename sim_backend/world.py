"""The thesis's world: a bounded arena of patches, one object, a home, and
the potential field robots emit when they hold the object.

Coordinates are NetLogo's: patch centres at integers from -worldSize to
+worldSize, x east, y north, home at (homeX, homeY) = (-15, -15). Grids are
flat Python lists indexed by `idx`, the fastest scalar access in CPython;
the vectorised engine keeps the same grids as numpy arrays.
"""

from __future__ import annotations

import functools

from firmware_logic import fixedpoint as fx
from firmware_logic.rng import Rng
from sim_backend import arena, faults, kernel, objects
from sim_backend.kernel import BLUE, FREE, OBSTACLE, YELLOW  # noqa: F401  (the cell values)
from sim_backend.scenario import CHOICES, Scenario


def signal_table(radius: int) -> list[tuple[int, int, int]]:
    """(dx, dy, increment) of Signal (kernel.signal_value) on every patch
    within sigRadius of the source patch, by patch centres."""
    return list(_signal_table(radius))


@functools.lru_cache(maxsize=None)
def _signal_table(radius: int) -> tuple[tuple[int, int, int], ...]:
    # every world of a sweep builds it (fixed-point square roots per patch)
    out = []
    for ddy in range(-radius, radius + 1):
        for ddx in range(-radius, radius + 1):
            d2 = ddx * ddx + ddy * ddy
            if d2 <= radius * radius:
                v = kernel.signal_value(d2 * fx.ONE * fx.ONE)
                if v:
                    out.append((ddx, ddy, v))
    return tuple(out)


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


class _Once:
    """What a World takes from its scenario alone, the same for every seed."""

    def __init__(self, sc: Scenario) -> None:
        n = 2 * sc.worldSize + 1
        self.table = _signal_table(sc.sigRadius)
        self.tdx = tuple(t[0] for t in self.table)
        self.tdy = tuple(t[1] for t in self.table)
        self.tv = tuple(t[2] for t in self.table)
        self.pieces = sc.pieces()
        self.decoy_cells = [c for p in self.pieces[1:] for c in p.placed(*p.at)]
        self.obstacle_cells = [c for p in sc.obstacles for c in p.placed(*p.at)]
        obj = [FREE] * (n * n)
        for x, y in self.decoy_cells:
            obj[kernel.cell(sc.worldSize, n, x, y)] = YELLOW
        for x, y in self.obstacle_cells:
            obj[kernel.cell(sc.worldSize, n, x, y)] = OBSTACLE
        self.obj = tuple(obj)
        # the arena's rules (kernel.DYNAMIC, YIELD flags; 0 the thesis's)
        self.rules = (kernel.DYNAMIC if sc.field == arena.FIELD_MODES[1] else 0) | \
            (kernel.YIELD if sc.crowd == arena.CROWD_MODES[1] else 0) | \
            (kernel.WRAP if sc.wrap else 0) | \
            (kernel.SELF_COUNTS if sc.probeSelf == "netlogo" else 0) | \
            (kernel.TOWARDS if sc.uphillHeading == "netlogo" else 0)
        # the NetLogo options the kernel reads (scenario.CHOICES; index 0 the default)
        self.sigmode = CHOICES["signalMode"].index(sc.signalMode)
        self.ties = CHOICES["uphillTies"].index(sc.uphillTies)
        # activation (kernel.SYNC, SEQUENTIAL): with SEQUENTIAL the engine draws
        # an order every go iteration and applies each robot's actions at once
        self.act = CHOICES["activation"].index(sc.activation)
        self.multi_step = multi_step(sc)
        self.faulty = int(faults.active(sc))


# (scenario, its _Once) of the last scenario a World was made of: a batch
# makes hundreds of Worlds of one scenario object. Held by identity (a
# scenario is frozen, and the pair keeps it alive, so no other can take its
# id); one store, so threads building batches at once each see a whole pair.
_ONCE: list[tuple[Scenario, _Once] | None] = [None]


def _per_scenario(sc: Scenario) -> _Once:
    last = _ONCE[0]
    if last is None or last[0] is not sc:
        last = _ONCE[0] = (sc, _Once(sc))
    return last[1]


class World:
    def __init__(self, sc: Scenario, seed: int):
        self.sc = sc
        self.seed = seed
        self.w = sc.worldSize
        self.n = 2 * sc.worldSize + 1
        size = self.n * self.n
        once = _per_scenario(sc)
        self.obj = list(once.obj)        # the decoys and obstacles placed
        self.owner = [0] * size          # node holding a BLUE patch
        self.field = [0] * size
        self.occ = [0] * size            # robots per patch at the tick's start
        self.stamp = [-1] * size         # tick in which a patch was last entered
        self.table = list(once.table)
        self.tdx, self.tdy, self.tv = list(once.tdx), list(once.tdy), list(once.tv)
        setup = Rng(seed, 0)             # the observer's stream, as in setup
        # CreateWorld: objx, objy = random 10 (the target's, when not given)
        pieces = once.pieces
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
        self.decoy_cells = list(once.decoy_cells)
        self.obstacle_cells = list(once.obstacle_cells)
        for x, y in self.object_cells:
            self.obj[self.idx(x, y)] = YELLOW
        for x, y in self.obstacle_cells:     # an obstacle over the object stays one
            self.obj[self.idx(x, y)] = OBSTACLE
        self.rules = once.rules
        self.xs: list[int] = []
        self.ys: list[int] = []
        if sc.starts == "netlogo":
            self._netlogo_starts(sc, seed, setup)
        else:
            self._redrawn_starts(sc, setup)
        # the world state the kernel reads (sim_backend/kernel.py): this one
        # run's grids, robots (kernel.ROBOT_FIELDS) and run (kernel.RUN_FIELDS,
        # one value each); the lists are also the World's attributes below
        a = sc.agents
        rows = {name: [0] * a for name in kernel.ROBOT_FIELDS}
        rows["xs"], rows["ys"] = self.xs, self.ys
        rows["held"] = [-1] * a          # held cell, -1: none
        rows["claim"] = [-1] * a
        rows["beacon_set"] = [-1] * a
        rows["tie"] = [kernel.tie_seed(seed, node) for node in range(1, a + 1)]
        rows["order"] = list(range(a))
        # faults (sim_backend/faults.py): the run's plan
        rows["die"], rows["stuck0"], rows["stuck1"], rows["flags"] = faults.plan(sc, seed)
        self.rb = kernel.Robots([rows[name] for name in kernel.ROBOT_FIELDS])
        for name in kernel.ROBOT_FIELDS:
            setattr(self, name, rows[name])
        # the NetLogo options the kernel reads (scenario.CHOICES; index 0 the default)
        self.sigmode, self.ties, self.act = once.sigmode, once.ties, once.act
        self.field_state, self.extra_steps = once.multi_step
        fseed, miss, ghost, noise = faults.per_run(sc, seed)
        run = {"base": 0, "w": self.w, "n": self.n, "lo": 0, "hi": a, "t0": 0,
               "t1": len(self.tv), "c0": 0, "c1": len(self.object_cells), "live": 1,
               "sigmode": self.sigmode, "radius": sc.sigRadius, "ties": self.ties,
               "act": self.act, "order_rng": kernel.order_seed(seed),
               "field_state": self.field_state, "extra_steps": self.extra_steps,
               "rules": self.rules, "faulty": once.faulty, "fseed": fseed,
               "miss": miss, "ghost": ghost, "noise": noise}
        self.run = kernel.Run([[run.get(name, 0)] for name in kernel.RUN_FIELDS])
        self.order_state = self.run.order_rng
        cx, cy, cv, cw = self.cell_arrays()
        self.grid = kernel.Grid((self.obj, self.owner, self.field, self.occ, self.stamp),
                                (self.tdx, self.tdy, self.tv), (cx, cy, cv, cw))
        # kernel.recount's count on a grid still all zero: its pass clearing
        # the grid was a tenth of a batch's worlds (tests/test_world.py)
        occ, w, n, patch, cell = self.occ, self.w, self.n, fx.patch, kernel.cell
        for x, y in zip(self.xs, self.ys):
            occ[cell(w, n, patch(x), patch(y))] += 1

    def _redrawn_starts(self, sc: Scenario, setup: Rng) -> None:
        """Our CreateSwarm: each robot walks `random max-pxcor` from the origin
        along a `random 360` heading; a start on the object or on another
        robot is redrawn, and the robot draws its own heading afresh."""
        taken = set()
        xs, ys, obj, w, n = self.xs, self.ys, self.obj, self.w, self.n
        below, dx, dy, patch, one = setup.below, fx.dx, fx.dy, fx.patch, fx.ONE
        inside, cell = kernel.inside, kernel.cell
        while len(xs) < sc.agents:
            h = below(360)
            dist = below(w) * one
            x = dx(h, dist)
            y = dy(h, dist)
            p = (px, py) = (patch(x), patch(y))
            if not inside(w, px, py) or obj[cell(w, n, px, py)] != FREE or p in taken:
                continue
            taken.add(p)
            xs.append(x)
            ys.append(y)

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

    def to_kernel(self, tick: int) -> None:
        """The tick and the carried object's cells into the kernel's state."""
        self.run.tick[0] = tick
        g = self.grid
        g.cx, g.cy, g.cv, g.cw = self.cell_arrays()
        self.run.c1[0] = len(g.cx)

    def from_kernel(self) -> None:
        """The carried object's cells back from the kernel's state."""
        self.object_cells = list(zip(self.grid.cx, self.grid.cy))

    def apply(self, tick: int) -> None:
        """Apply the robots' intents of this tick (kernel.apply_tick)."""
        self.to_kernel(tick)
        kernel.apply_tick(self.grid, self.rb, self.run, 0)
        self.from_kernel()

    def draw_order(self) -> list[int]:
        """A go iteration's order of robot indices (kernel.draw_order)."""
        kernel.draw_order(self.rb, self.run, 0)
        return list(self.order)

    def apply_robot(self, i: int) -> None:
        """Robot i's claim and move of its last step, at once (kernel.apply_robot)."""
        kernel.apply_robot(self.grid, self.rb, self.run, 0, i)

    def idx(self, px: int, py: int) -> int:
        return (py + self.w) * self.n + (px + self.w)

    def inside(self, px: int, py: int) -> bool:
        return -self.w <= px <= self.w and -self.w <= py <= self.w

    def recount(self) -> None:
        kernel.recount(self.grid, self.rb, self.run, 0)

    def uphill(self, i: int) -> int:
        """kernel.uphill for robot index i."""
        return kernel.uphill(self.grid, self.rb, self.run, 0, i)

    def signal(self, px: int, py: int, sign: int = 1) -> None:
        """Add (or, sign=-1, remove) one beacon's field centred on a patch."""
        kernel.signal(self.grid, self.run, 0, px, py, sign)
