"""The physics both device emulators share: a differential-drive robot in
the sim world (mm pose, wheel arcs, collisions, beacon field), and the
clock its wheels run on. The protocol sides of the emulators stay separate;
only the world they drive is shared.

Clocks: `SystemClock` (the default) is wall time. `SimClock` moves only
when told (`advance`, `sleep`); a test shares one with the emulator and the
body under test, so how far a wheel turns depends on the simulated time
between two commands, never on how loaded the machine is. Bytes on the
wire take no simulated time (`wire_time` False): the emulator still sleeps
the line time, but only in wall time.
"""

from __future__ import annotations

import math
import threading
import time

from firmware_logic import fixedpoint as fx
from sim_backend.world import FREE


class SystemClock:
    """Wall time (time.monotonic)."""

    wire_time = True

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


class SimClock:
    """Simulated seconds that pass only when the test (or a body) says so."""

    wire_time = False

    def __init__(self, start: float = 0.0) -> None:
        self._t = start
        self._lock = threading.Lock()

    def now(self) -> float:
        return self._t

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            with self._lock:
                self._t += seconds

    advance = sleep


class WorldRobot:
    """Mixin; the emulator sets world, index, patch_mm, x_mm, y_mm, theta
    (degrees, 0 = north) and beacon_src."""

    world: object | None
    index: int
    patch_mm: float
    x_mm: float
    y_mm: float
    theta: float
    beacon_src: tuple[int, int] | None

    def _drive(self, dl_mm: float, dr_mm: float, wheel_base_mm: float) -> None:
        """Move along the arc the two wheels travelled; blocked moves slip."""
        dth = math.degrees((dl_mm - dr_mm) / wheel_base_mm)
        d = (dl_mm + dr_mm) / 2
        mid = math.radians(self.theta + dth / 2)
        nx = self.x_mm + d * math.sin(mid)
        ny = self.y_mm + d * math.cos(mid)
        self.theta = (self.theta + dth) % 360
        if self.world is not None and self._blocked(nx, ny):
            return                      # pushing against something: the wheels slip
        self.x_mm, self.y_mm = nx, ny
        if self.world is not None:
            w = self.world
            w.xs[self.index] = int(round(nx * 256 / self.patch_mm))
            w.ys[self.index] = int(round(ny * 256 / self.patch_mm))
            w.recount()

    def _patch(self, x_mm: float, y_mm: float) -> tuple[int, int]:
        # the world's own rounding (Q8 -> patch), so occupancy agrees with it
        return (fx.patch(int(round(x_mm * 256 / self.patch_mm))),
                fx.patch(int(round(y_mm * 256 / self.patch_mm))))

    def _blocked(self, x_mm: float, y_mm: float) -> bool:
        w = self.world
        p = self._patch(x_mm, y_mm)
        if p == self._patch(self.x_mm, self.y_mm):
            return False
        if not w.inside(*p):
            return True
        k = w.idx(*p)
        return w.obj[k] != FREE or w.occ[k] > 0

    def _look(self, bearing: float) -> tuple[int, int]:
        th = math.radians(self.theta + bearing)
        return self._patch(self.x_mm + self.patch_mm * math.sin(th),
                           self.y_mm + self.patch_mm * math.cos(th))

    def _beacon(self, on: int) -> None:
        if self.world is None:
            return
        if on and self.beacon_src is None:
            self.beacon_src = self._patch(self.x_mm, self.y_mm)
            self.world.signal(*self.beacon_src)
        elif not on and self.beacon_src is not None:
            self.world.signal(*self.beacon_src, sign=-1)
            self.beacon_src = None
