"""What the host-side robot bodies (Khepera II, GoGo) share: a pose kept in
millimetres and reported to the firmware in Q8 patches, messaging over an
engine Link (sim_backend/link.py) or nowhere, and the tick.

The tick. A body never blocks for long: `forward`, `claim` and `carry`
start a motion (a queue of phases: turn, then drive) and return; the runner
calls `begin_tick()` once per tick, which checks the motion's progress (and
stops or steers the wheels) and forgets the previous tick's readings. The
firmware is stepped only while the body is idle (`tick(robot)` does both),
so each FSM step sees a finished move, as in the simulator. Sensing reads
the device at most once per query kind per tick and answers every later
call of that tick from the snapshot, which is also the HAL's contract
(firmware_logic/hal.py: answered from the world as it stood at the start
of the tick).

Time: bodies take a `clock` (`now()`, `sleep(s)`, `wire_time`); the default
is the wall clock. Tests pass a simulated clock shared with the device
emulator, so a motion's length does not depend on how busy the machine is.
"""

from __future__ import annotations

import time
from typing import Callable, Protocol

from firmware_logic import fixedpoint as fx
from firmware_logic import messages as msg
from firmware_logic.hal import Hal


class Clock(Protocol):
    wire_time: bool                 # does time pass while bytes are on the wire?

    def now(self) -> float: ...

    def sleep(self, seconds: float) -> None: ...


class WallClock:
    """time.monotonic; bytes take real time on the wire."""

    wire_time = True

    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        if seconds > 0:
            time.sleep(seconds)


class Phase:
    """One step of a motion: a turn to `heading`, or a drive of `mm`."""

    __slots__ = ("kind", "heading", "mm", "ticks", "x0", "y0", "t_on", "seconds", "sign")

    def __init__(self, kind: str, heading: float = 0.0, mm: float = 0.0) -> None:
        self.kind = kind
        self.heading = heading
        self.mm = mm
        self.ticks = 0              # ticks this phase has been running
        self.x0 = self.y0 = 0.0     # where a drive started
        self.t_on = -1.0            # when the motors went on (timed bodies); -1: not yet
        self.seconds = 0.0          # planned motor time (timed bodies)
        self.sign = 1.0

    def __repr__(self) -> str:
        return ("turn to %.1f" % self.heading if self.kind == TURN
                else "drive %.1f mm" % self.mm)


TURN = "turn"
DRIVE = "drive"


class HostBody(Hal):
    """Base of a HAL driven from the host; subclasses implement the sensing
    calls, `_advance()` (progress of the motion, called once per tick) and
    `_begin()` (start the first phase of a new motion)."""

    def __init__(self, node: int, link: object | None, patch_mm: float, x_mm: float,
                 y_mm: float, heading: float, clock: Clock | None) -> None:
        self.node = node
        self.link = link
        self.patch_mm = patch_mm
        self.x_mm, self.y_mm, self.theta = x_mm, y_mm, heading % 360
        self.clock: Clock = clock if clock is not None else WallClock()
        self.ticks = 0
        self.phases: list[Phase] = []
        self.claimed = -1
        self.beacon_on = 0
        self.abandoned = 0          # motions given up after their tick budget
        self._snap: dict[object, object] = {}

    # -- the tick -------------------------------------------------------------------

    def begin_tick(self) -> None:
        """A new tick: forget the last tick's readings, advance the motion.
        A SerialLinkError leaves the body consistent; call again next tick."""
        self.ticks += 1
        self._snap.clear()
        self._resume()
        if self.phases:
            self._advance()

    def busy(self) -> bool:
        """A motion is in progress; the firmware waits for it to end."""
        return bool(self.phases)

    def tick(self, robot: object) -> bool:
        """One tick of the firmware on this body; True if the FSM stepped."""
        self.begin_tick()
        if self.busy():
            return False
        robot.step(self)            # type: ignore[attr-defined]
        return True

    def settle(self, between: Callable[[], None], max_ticks: int = 1000) -> int:
        """Run ticks until the motion ends (for scripts and tests that act
        without the firmware); `between()` lets a tick's time pass. Returns
        the ticks taken; the motion's own tick budget bounds it."""
        n = 0
        while self.busy() and n < max_ticks:
            between()
            self.begin_tick()
            n += 1
        return n

    def _reading(self, key: object, read: Callable[[], object]) -> object:
        """`read()` once per tick; later calls this tick get the snapshot."""
        try:
            return self._snap[key]
        except KeyError:
            v = self._snap[key] = read()
            return v

    def _start(self, phases: list[Phase]) -> None:
        # a new intent supersedes a motion still under way: the firmware's
        # latest decision wins, and the pose already covers what was done
        self.phases = phases
        if phases:
            self._begin()

    def _resume(self) -> None:
        """Recover from a lost port before the tick (default: nothing to do)."""

    def _advance(self) -> None:
        raise NotImplementedError

    def _begin(self) -> None:
        raise NotImplementedError

    # -- pose -----------------------------------------------------------------------

    def _refresh_pose(self) -> None:
        """Bring the pose up to this tick (odometry bodies read it here)."""

    def _q8(self, mm: float) -> int:
        return int(round(mm * fx.ONE / self.patch_mm))

    def x(self) -> int:
        self._refresh_pose()
        return self._q8(self.x_mm)

    def y(self) -> int:
        self._refresh_pose()
        return self._q8(self.y_mm)

    # -- messages -------------------------------------------------------------------

    def send(self, kind: int, a0: int, a1: int, a2: int, a3: int, a4: int, a5: int) -> None:
        if self.link is not None:
            n = len(msg.fields(kind))
            self.link.robot_send(self.node, kind, (a0, a1, a2, a3, a4, a5)[:n])  # type: ignore[attr-defined]

    def recv(self, buf: list) -> int:
        if self.link is None:
            return 0
        m = self.link.robot_recv(self.node)  # type: ignore[attr-defined]
        if m is None:
            return 0
        kind, fields = m
        for j, v in enumerate(fields):
            buf[j] = v
        return kind
