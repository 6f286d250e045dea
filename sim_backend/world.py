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
from sim_backend import objects
from sim_backend.scenario import Scenario

FREE = 0
YELLOW = 1   # a free object segment
BLUE = 2     # a segment a robot holds


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
        self.table = signal_table(sc.sigRadius)
        setup = Rng(seed, 0)             # the observer's stream, as in setup
        # CreateWorld: objx, objy = random 10
        self.obj_x = sc.objectX if sc.objectX is not None else setup.below(10)
        self.obj_y = sc.objectY if sc.objectY is not None else setup.below(10)
        self.object_cells = objects.cells(sc.object, self.obj_x, self.obj_y)
        for x, y in self.object_cells:
            self.obj[self.idx(x, y)] = YELLOW
        # CreateSwarm: each robot faces `random 360` and walks `random max-pxcor`
        # from the origin; a start on the object or on another robot is redrawn.
        self.xs: list[int] = []
        self.ys: list[int] = []
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
        self.recount()

    def idx(self, px: int, py: int) -> int:
        return (py + self.w) * self.n + (px + self.w)

    def inside(self, px: int, py: int) -> bool:
        return -self.w <= px <= self.w and -self.w <= py <= self.w

    def recount(self) -> None:
        occ = [0] * (self.n * self.n)
        for x, y in zip(self.xs, self.ys):
            occ[self.idx(fx.patch(x), fx.patch(y))] += 1
        self.occ = occ

    def signal(self, px: int, py: int, sign: int = 1) -> None:
        """Add (or, sign=-1, remove) one beacon's field centred on a patch."""
        for ddx, ddy, v in self.table:
            x = px + ddx
            y = py + ddy
            if self.inside(x, y):
                self.field[self.idx(x, y)] += sign * v
