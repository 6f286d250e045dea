"""A mission in which chosen robots are real bodies and the rest simulated.

The simulated swarm is the ordinary tick engine (sim_backend/engine.py),
used as it is: the robots of the chosen nodes are swapped, in the engine's
own `robots` and `bodies` lists, for a `HostNode` (the node's unchanged FSM,
stepped on its real body) and a `Seat` (that body's place in the sim world).
The engine's tick rule (docs/tick-semantics.md) is not rewritten; the real
robots' intents go through it like any other robot's:

- a real robot's pose in the sim world is its body's own odometry (Khepera)
  or dead reckoning (GoGo), copied into the world after every tick, so the
  simulated robots see it as a robot in that patch and do not enter it;
- its beacon LED, claim and carry steps are also given to the engine as
  intents: the LED adds the Signal field the simulated robots follow, a claim
  marks the sim segment held, a carry step joins the carried group;
- its senses are its own: it touches the real object and sees real light,
  not the simulated robots or their beacons;
- its messages go over the engine's link to the same host coordinator as
  every simulated robot's, so the coordinator collects all touches.

A real body's motion takes several ticks (bridge/serial/hostbody.py: the
FSM steps only while the body is idle). The mission paces ticks on a clock:
the wall clock on a bench, a SimClock shared with the device emulators in
tests (then no test result depends on how loaded the machine is).
"""

from __future__ import annotations

import contextlib
import logging
from typing import Any, Callable, Protocol, runtime_checkable

from bridge.bodies import BodyContext, BodySpec, BodyURLError, OpenedBody, open_body
from bridge.errors import BridgeError
from firmware_logic import fixedpoint as fx
from firmware_logic import hal
from firmware_logic.hal import Hal

log = logging.getLogger(__name__)

DEFAULT_TICK_S = 0.05
LOST_TICKS = 200                # a body silent this many ticks in a row ends the mission


class MissionError(BridgeError):
    """A real body failed for good during the mission (exit status 1)."""


class Seat(Hal):
    """A real body's place in the engine: the HAL the node's FSM is stepped
    on (every call goes to the real body) and the intents the engine applies
    for that node with its own rule (sim_backend/kernel.py), written where
    SimBody writes them: the world's per-robot intent arrays at index i."""

    def __init__(self, host: Any, world: Any, index: int, node: int) -> None:
        self.host = host                # a bridge.serial.hostbody.HostBody
        self.world = world
        self.i = index
        self.node = node
        self.reset_intents()

    @property
    def held(self) -> int:
        return self.world.held[self.i]

    def reset_intents(self) -> None:
        # never a forward move: where a real robot is comes from its odometry
        w = self.world
        w.mv_on[self.i] = 0
        w.claim[self.i] = -1
        w.beacon_set[self.i] = -1

    def sync(self) -> None:
        """Copy the body's pose into the world, clamped to the arena (odometry
        may drift past a wall; the world's grids end there)."""
        w = self.world
        lim = w.w * fx.ONE + fx.ONE // 2 - 1
        w.xs[self.i] = max(-lim, min(lim, self.host.x()))
        w.ys[self.i] = max(-lim, min(lim, self.host.y()))

    # -- sensing: the real body's own -------------------------------------------------

    def x(self) -> int:
        return self.host.x()

    def y(self) -> int:
        return self.host.y()

    def probe(self, heading: int) -> int:
        return self.host.probe(heading)

    def field_ahead(self, heading: int) -> int:
        return self.host.field_ahead(heading)

    def field_here(self) -> int:
        return self.host.field_here()

    def uphill(self) -> int:
        return self.host.uphill()

    def holding(self) -> int:
        return self.host.holding()

    # -- acting: the real body moves; the engine hears the same intent ------------------

    def forward(self, heading: int, step: int) -> None:
        self.host.forward(heading, step)

    def claim(self, heading: int) -> None:
        self.host.claim(heading)
        w = self.world
        px = fx.patch(w.xs[self.i] + fx.dx(heading, fx.ONE))
        py = fx.patch(w.ys[self.i] + fx.dy(heading, fx.ONE))
        if w.inside(px, py):
            w.claim[self.i] = w.idx(px, py)

    def carry(self, dx: int, dy: int) -> None:
        self.host.carry(dx, dy)
        w = self.world
        w.carry_on[self.i] = 1
        w.carry_dx[self.i] = dx
        w.carry_dy[self.i] = dy

    def beacon(self, on: int) -> None:
        self.host.beacon(on)
        self.world.beacon_set[self.i] = on if on in (hal.BEACON_OFF, hal.BEACON_LEADER) \
            else hal.BEACON_ON

    # -- messages: over the engine's link, to the host coordinator ----------------------

    def send(self, kind: int, a0: int, a1: int, a2: int, a3: int, a4: int, a5: int) -> None:
        self.host.send(kind, a0, a1, a2, a3, a4, a5)

    def recv(self, buf: list) -> int:
        return self.host.recv(buf)


class HostNode:
    """The engine's robot entry for a real body: the node's own FSM, stepped
    only on ticks its body is idle (a move takes several ticks)."""

    def __init__(self, fsm: Any, opened: OpenedBody) -> None:
        self.fsm = fsm
        self.opened = opened
        self.steps = 0                  # ticks the FSM stepped
        self.failed_ticks = 0           # ticks the device failed, over the mission
        self.lost_streak = 0

    def __getattr__(self, name: str) -> Any:
        # plots and records read the FSM's state like any robot's
        return getattr(self.fsm, name)

    def step(self, seat: Seat) -> None:
        from bridge.serial.errors import SerialLinkError
        host = seat.host
        try:
            host.begin_tick()
            if not host.busy():
                self.fsm.step(seat)
                self.steps += 1
            seat.sync()
        except SerialLinkError as err:
            # the drivers leave the body consistent and reopen the port on the
            # next call: a robot unplugged for a moment costs ticks, not the run
            self.failed_ticks += 1
            self.lost_streak += 1
            if self.lost_streak == 1:
                log.warning("node %d (%s): %s; retrying every tick", seat.node,
                            self.opened.describe(), err)
            if self.lost_streak >= LOST_TICKS:
                raise MissionError(f"node {seat.node} ({self.opened.describe()}) failed "
                                   f"{self.lost_streak} ticks in a row: {err}") from err
            return
        if self.lost_streak:
            log.warning("node %d (%s) is back after %d ticks", seat.node,
                        self.opened.describe(), self.lost_streak)
            self.lost_streak = 0


class TetherNode:
    """The engine's robot entry for a board running its own FSM: nothing to
    step here (the board ticks itself; its SENSOR / ACTION frames are served
    by the tether)."""

    def __init__(self, fsm: Any, opened: OpenedBody) -> None:
        self.fsm = fsm                  # the host's copy, never stepped
        self.opened = opened

    def __getattr__(self, name: str) -> Any:
        return getattr(self.fsm, name)

    def step(self, body: Any) -> None:
        pass


@runtime_checkable
class HeldBack(Protocol):
    """A body whose intents wait for its board's tick end (tether_seat's)."""

    def activate(self) -> None: ...


def tether_seat(world: Any, index: int, node: int, link: Any) -> Any:
    """A SimBody whose intents come from a board over the tether. They are
    held back until the board ends its tick (ACTION END), then applied by the
    engine's own rule (MixedLink's apply); the engine's tick neither resets
    nor applies them half-way through a board tick."""
    from sim_backend.body import SimBody

    class TetherSeat(SimBody):
        def __init__(self) -> None:
            self.pending: list[tuple[Any, tuple[int, ...]]] = []
            super().__init__(world, index, node, link)

        def forward(self, heading: int, step: int) -> None:
            self.pending.append((SimBody.forward, (heading, step)))

        def claim(self, heading: int) -> None:
            self.pending.append((SimBody.claim, (heading,)))

        def carry(self, dx: int, dy: int) -> None:
            self.pending.append((SimBody.carry, (dx, dy)))

        def beacon(self, on: int) -> None:
            self.pending.append((SimBody.beacon, (on,)))

        def activate(self) -> None:
            for act, args in self.pending:
                act(self, *args)
            self.pending.clear()

    return TetherSeat()


class MixedLink:
    """The engine's link: in-process for the nodes stepped here (simulated
    and host-side real ones), a tether (sim_backend/emulators/tether.py)
    over each MicroPython board's serial port for the others. The tether is
    given this object as its engine: `bodies` are the engine's, `_apply`
    applies only the boards' held-back intents."""

    def __init__(self, engine_nodes: list[int]) -> None:
        from sim_backend.engine import InprocLink
        self.inner = InprocLink(engine_nodes)
        self.engine: Any = None
        self.tethers: dict[int, Any] = {}          # node -> TetherTransport
        self.inbox: list[tuple[int, int, tuple]] = []

    @property
    def bodies(self) -> list[Any]:
        return self.engine.bodies

    def _apply(self) -> None:
        eng = self.engine
        for b in eng.bodies:
            b.reset_intents()           # what the engine's tick already applied
        for b in eng.bodies:
            if isinstance(b, HeldBack):
                b.activate()
        eng._apply()

    def robot_send(self, node: int, kind: int, fields: tuple) -> None:
        self.inner.robot_send(node, kind, fields)

    def robot_recv(self, node: int) -> tuple[int, tuple] | None:
        return self.inner.robot_recv(node)

    def pump(self, timeout: float) -> None:
        """Serve the boards for up to `timeout` s (every read has a timeout)."""
        for t in self.tethers.values():
            self.inbox += t.poll(timeout / max(1, len(self.tethers)))

    def poll(self, timeout: float) -> list[tuple[int, int, tuple]]:
        self.pump(timeout)
        out, self.inbox = self.inner.poll(0) + self.inbox, []
        return out

    def send(self, node: int, kind: int, fields: tuple) -> None:
        if node in self.tethers:
            self.tethers[node].send(node, kind, fields)
            return
        self.inner.send(node, kind, fields)
        if node == 0:
            for n, t in self.tethers.items():
                self.inner.down[n].clear()      # nobody here reads a board's queue
                t.send(node, kind, fields)

    def bad_frames(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for t in self.tethers.values():
            for k, v in t.bad_frames().items():
                out[k] = out.get(k, 0) + v
        return out

    def close(self) -> None:
        pass                            # the tethers' ports belong to their bodies


class MixedMission:
    """One scenario with some nodes on real bodies; a context manager that
    closes every body it opened (motors stopped, LEDs off).

    `bodies`: node -> parsed body URL (sim:// nodes stay simulated).
    `clock`: paces the ticks (`now()`, `sleep()`); None: the wall clock.
    """

    def __init__(self, sc: Any, seed: int, bodies: dict[int, BodySpec],
                 tick_s: float = DEFAULT_TICK_S, clock: Any = None) -> None:
        from bridge.serial.hostbody import WallClock
        from sim_backend.engine import Engine

        for node in bodies:
            if not 1 <= node <= sc.agents:
                raise BodyURLError(f"--body {node}=...: node {node} is not a robot of the "
                                   f"scenario (1..{sc.agents})")
        if tick_s <= 0:
            raise BodyURLError(f"tick {tick_s} s: expected a positive period")
        real = sorted(n for n, spec in bodies.items() if spec.scheme != "sim")
        if getattr(sc, "wrap", False) and real:
            # a robot on a real floor cannot leave one edge and enter at the other
            raise BodyURLError(f"--body {real[0]}=...: wrap = true needs every robot "
                               "simulated; a real body cannot cross an edge of the torus")
        self.sc = sc
        self.seed = seed
        self.tick_s = tick_s
        self.clock = clock if clock is not None else WallClock()
        self.link = MixedLink(list(range(1, sc.agents + 1)))
        self.engine = Engine(sc, seed, link=self.link)
        self.link.engine = self.engine
        self.opened: dict[int, OpenedBody] = {}
        self.hosts: dict[int, HostNode] = {}
        self.tethered: dict[int, TetherNode] = {}
        self._stack = contextlib.ExitStack()
        try:
            for node, spec in sorted(bodies.items()):
                self._attach(node, spec)
        except BaseException:
            self._stack.close()
            raise

    def _attach(self, node: int, spec: BodySpec) -> None:
        eng = self.engine
        i = node - 1
        w = eng.world
        ctx = BodyContext(node=node, x_patch=fx.patch(w.xs[i]), y_patch=fx.patch(w.ys[i]),
                          arena=w.w, tick_s=self.tick_s, clock=self.clock, link=eng.link)
        opened = self._stack.enter_context(open_body(spec, ctx))
        self.opened[node] = opened
        if opened.kind == "sim":
            return
        if opened.kind == "tether":
            from sim_backend.emulators.tether import TetherTransport
            if "x" in spec.options or "y" in spec.options:
                w.xs[i] = int(round(spec.get("x", ctx.x_patch) * fx.ONE))
                w.ys[i] = int(round(spec.get("y", ctx.y_patch) * fx.ONE))
            seat = tether_seat(w, i, node, eng.link)
            self._check_start(seat, spec.url)
            eng.bodies[i] = seat
            eng.robots[i] = self.tethered[node] = TetherNode(eng.robots[i], opened)
            self.link.tethers[node] = TetherTransport(opened.transport, self.link, [node])
            return
        seat = Seat(opened.hal, w, i, node)
        seat.sync()
        self._check_start(seat, spec.url)
        eng.bodies[i] = seat
        eng.robots[i] = self.hosts[node] = HostNode(eng.robots[i], opened)

    def _check_start(self, seat: Seat, url: str) -> None:
        """The patch where the real robot was put down must be free in the
        sim world too, or the two worlds disagree from the first tick."""
        w = self.engine.world
        px, py = fx.patch(w.xs[seat.i]), fx.patch(w.ys[seat.i])
        if w.obj[w.idx(px, py)]:
            raise BodyURLError(f"body {url!r} (node {seat.node}): start patch ({px}, {py}) "
                               f"is on the object; put the robot down elsewhere (x=, y=)")
        for j, (x, y) in enumerate(zip(w.xs, w.ys)):
            if j != seat.i and (fx.patch(x), fx.patch(y)) == (px, py):
                raise BodyURLError(f"body {url!r} (node {seat.node}): start patch ({px}, {py}) "
                                   f"is taken by "
                                   f"simulated robot {j + 1}; put the robot down elsewhere "
                                   f"(x=, y= in its URL) or pick another --seed")
        w.recount()

    # -- running ----------------------------------------------------------------------

    def describe(self) -> dict[int, str]:
        return {n: o.describe() for n, o in sorted(self.opened.items())}

    def start_poses(self) -> dict[int, tuple[int, int, float]]:
        """node -> (patch x, patch y, heading) where each real robot must be put down."""
        w = self.engine.world
        return {n: (fx.patch(w.xs[n - 1]), fx.patch(w.ys[n - 1]), h.opened.hal.theta)
                for n, h in sorted(self.hosts.items())}

    def step(self) -> None:
        """One tick: the engine's, real nodes included (their FSMs step on
        their bodies, their intents join the others')."""
        self.engine.step()
        # applied: a board's END must not apply them a second time
        for b in self.engine.bodies:
            b.reset_intents()

    def run(self, max_ticks: int | None = None,
            until: Callable[["MixedMission"], bool] | None = None,
            progress: Callable[[int], None] | None = None) -> Any:
        """Tick until delivered, the scenario's maxTicks, `max_ticks` or
        until(self); returns the engine's RunResult."""
        from sim_backend.engine import RunResult
        eng = self.engine
        limit = min(max_ticks or eng.sc.maxTicks, eng.sc.maxTicks)
        due = self.clock.now()
        while not eng.finished() and eng.tick < limit:
            if until is not None and until(self):
                break
            self.step()
            if progress is not None:
                progress(eng.tick)
            # pace: a real robot's steering assumes one tick per tick_s; a
            # tick that ran long is not caught up with a burst of short ones
            due += self.tick_s
            now = self.clock.now()
            if now > due + self.tick_s:
                due = now
            self._wait(due - now)
        return RunResult(eng.sc, eng.seed, eng.tick, eng.world, eng.coordinator, eng.robots,
                         eng.trajectories)

    def _wait(self, seconds: float) -> None:
        """Let the rest of the tick pass; boards are served meanwhile (a board
        tick is a dozen request / answer round trips)."""
        if not self.tethered:
            self.clock.sleep(seconds)
            return
        end = self.clock.now() + seconds
        while True:
            self.link.pump(min(0.01, max(0.0, end - self.clock.now())))
            if self.clock.now() >= end:
                return
            if not self.clock.wire_time:        # a SimClock: serve once, then move on
                self.clock.sleep(end - self.clock.now())
                return

    def summary(self, result: Any) -> dict[str, Any]:
        s = result.summary()
        c = self.engine.coordinator
        s["duplicates"] = getattr(c, "duplicates", 0)
        s["bodies"] = {str(n): o.describe() for n, o in sorted(self.opened.items())}
        s["real_touches"] = {str(n): sum(1 for t in c.touches if t.node == n)
                             for n in sorted({*self.hosts, *self.tethered})}
        s["real_failed_ticks"] = {str(n): h.failed_ticks for n, h in sorted(self.hosts.items())}
        return s

    # -- context manager -----------------------------------------------------------------

    def close(self) -> None:
        self._stack.close()

    def __enter__(self) -> "MixedMission":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
