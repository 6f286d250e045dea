"""The per-robot reference tick engine.

Tick semantics (docs/tick-semantics.md):
  1. every robot, in node order, reads its inbox and steps its FSM against
     the world as it stood at the start of the tick; actions are intents;
  2. intents are applied in a fixed order: claims (lowest node wins a
     segment), beacons (Signal), the carried group, then moves in node order
     (a robot may not enter a patch that held a robot at the tick's start,
     holds the object, is off the arena, or that a lower node entered this
     tick; moving within its own patch is always allowed);
  3. messages robots sent travel over the link to the host coordinator
     (but those it declared muted: they would change nothing), whose
     commands reach the robots' inboxes before the next tick
     (sim_backend/exchange.py).
"""

from __future__ import annotations

import functools
import sys
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable

from sim_backend import registry
from sim_backend.coordinator import Ending, TruthMeasuring, has, measures_of
from sim_backend.link import Link
from sim_backend import kernel
from sim_backend.body import SimBody
from sim_backend.errors import EngineError
from sim_backend.exchange import exchange
from sim_backend.measures import polygon_iou, power_held, shape_iou
from sim_backend.scenario import Scenario
from sim_backend.world import World


class InprocLink:
    """In-process link: lists, delivered at the tick boundary."""

    def __init__(self, nodes: list[int]) -> None:
        self.up: list[tuple[int, int, tuple]] = []
        self.down: dict[int, deque] = {n: deque() for n in nodes}

    def robot_send(self, node: int, kind: int, fields: tuple) -> None:
        self.up.append((node, kind, tuple(fields)))

    def robot_recv(self, node: int) -> tuple[int, tuple] | None:
        q = self.down[node]
        return q.popleft() if q else None

    def poll(self, timeout: float) -> list[tuple[int, int, tuple]]:
        # every message is here already: nothing to wait for
        out, self.up = self.up, []
        return out

    def send(self, node: int, kind: int, fields: tuple) -> None:
        targets = self.down.values() if node == 0 else (self.down[node],)
        for q in targets:
            q.append((kind, tuple(fields)))

    def bad_frames(self) -> dict[str, int]:
        return {}                        # lists drop no frame

    def close(self) -> None:
        pass


@dataclass
class RunResult:
    """One finished run: its scenario and seed, the world and the
    coordinator as the run left them, the robots, and what the observers
    kept (trajectories, states per tick, measures); summary() is what
    `touchswarm run --json` prints."""

    scenario: Scenario
    seed: int
    ticks: int
    world: World
    coordinator: Any          # the behaviour's coordinator
    _robots: list[Any]        # the behaviour's FSMs (read them as `robots`)
    trajectories: list[tuple[list[int], list[int]]] = field(default_factory=list)
    states: list[list[int]] = field(default_factory=list)   # every robot's state per tick
    # FSM steps the swarm had taken when it converged (activation netlogo; -1:
    # not converged, or sync, where it is converged_tick x agents)
    conv_steps: int = -1
    # measures watching the run (e.g. perception's Perceiver): each
    # adds its summary() fields; see Engine.instruments
    instruments: list[Any] = field(default_factory=list)
    # writes the FSMs' final fields into them, at the first read of `robots`:
    # an engine that keeps them in arrays (soa) spends most of a big run's
    # end there, and a summary reads none of them
    fill: Callable[[], None] | None = field(default=None, repr=False, compare=False)
    # the measures the behaviour declares (declared_measures of its spec),
    # when the engine that ran it says; else the summary loads the behaviour
    declared: frozenset[str] | None = field(default=None, repr=False, compare=False)
    # perception's end fields (perception/tracker.py end_fields), when the
    # engine made a batch's at once (soa.run_batch); else the summary makes them
    end: dict[str, Any] | None = field(default=None, repr=False, compare=False)

    @property
    def robots(self) -> list[Any]:
        if self.fill is not None:
            fill, self.fill = self.fill, None
            fill()
        return self._robots

    @property
    def delivered(self) -> bool:
        return self.coordinator.delivered_tick >= 0

    def true_cells(self) -> list[tuple[int, int]]:
        return list(self.world.object_cells)

    def shape_iou(self) -> float:
        return shape_iou(self.coordinator, self.world)

    def converged_moves(self) -> float | None:
        """Convergence in robot moves: the FSM steps (each one move or touch,
        a thesis RandomHead or FollowField) a robot had taken on average.
        Under sync every robot steps once per tick, so it is converged_tick;
        under netlogo a robot in the behaviour's MULTI_STEP state steps 1 +
        its parameter's value times per go iteration (docs/tick-semantics.md)."""
        c = self.coordinator.converged_tick
        if c < 0:
            return None
        if self.scenario.activation == "sync":
            return float(c)
        if self.conv_steps < 0:
            return None                  # an engine that did not count them
        return round(self.conv_steps / self.scenario.agents, 2)

    def offered(self) -> dict[str, Callable[[], Any]]:
        """The measures the world computes for any behaviour, by name, each a
        function of this run. A summary holds one only when the behaviour
        declares it in spec.MEASURES: a dispersion run has no power or shape
        IoU (a behaviour's words appear only when it declares them)."""
        c = self.coordinator

        def tick(t: int) -> int | None:
            return t if t >= 0 else None
        return {
            "found_tick": lambda: tick(c.found_tick),
            "converged_tick": lambda: tick(c.converged_tick),
            "home_tick": lambda: tick(c.delivered_tick),
            "segments": lambda: [[t.sx, t.sy] for t in c.touches],
            "power": lambda: power_held(c),
            "shape_iou": self.shape_iou,
            "polygon_iou": lambda: polygon_iou(c, self.world),
            "leader": lambda: c.leader or None,
            "converged_moves": self.converged_moves,
        }

    def summary(self) -> dict:
        c = self.coordinator
        declared = self.declared
        if declared is None:
            declared = declared_measures(registry.load(self.scenario.behaviour).spec)
        return {
            "scenario": self.scenario.name,
            "seed": self.seed,
            "robots": self.scenario.agents,
            # the behaviour's own parameters, as the scenario set them
            **dict(self.scenario.params),
            "object": self.scenario.object,
            "ticks": self.ticks,
            # the host contract: where robots touched, and whether the
            # behaviour's goal was reached (its RESULT words say it)
            "touches": [[t.rx, t.ry] for t in c.touches],
            "delivered": self.delivered,
            "activation": self.scenario.activation,
            **{k: f() for k, f in self.offered().items() if k in declared},
            # how it ended (firmware_logic/roster.py OUTCOMES): a behaviour's
            # measures may say it in its own words (the thesis: no path home,
            # transporting, ...); `delivered` is true only with a delivered tick
            "outcome": run_outcome(c),
            **measures_of(c),
            # [[breeds]]: each touch's breed, in touch order
            **({"touch_breeds": [self.scenario.breed_name(t.node)
                                  for t in c.touches]}
               if self.scenario.breeds else {}),
            **self.truth_measures(),
            **self.perception(),
        }

    def perception(self) -> dict:
        """The watching measures' fields (a Perceiver's: the shape estimate
        and the verdict); a run no Perceiver watched (a sweep's) still gets
        estimate_iou, recognised and p, from its end state
        (perception/tracker.py end_fields)."""
        out = {k: v for inst in self.instruments for k, v in inst.summary().items()}
        if "estimate_iou" not in out:
            if self.end is not None:
                out.update(self.end)
            else:
                from perception.tracker import end_fields
                out.update(end_fields(self))
        return out

    def truth_measures(self) -> dict:
        """The coordinator's measures that need the truth it is not told (the
        target's cells): its truth_measures(cells), when it has them."""
        c = self.coordinator
        if not has(c, TruthMeasuring) or not self.world.start_cells:
            return {}
        # the target's cells as the world placed them at the start (the
        # scenario's first piece at obj_x, obj_y; none without a piece)
        return c.truth_measures(set(self.world.start_cells))


@functools.lru_cache(maxsize=64)
def declared_measures(spec: Any) -> frozenset[str]:
    """The measures a behaviour's spec declares (spec.MEASURES' names): read
    once per loaded spec, not once per summary."""
    return frozenset(name for name, _ in spec.MEASURES)


UNTIL = ("delivered", "converged")


def run_ended(c: Any, until: str) -> bool:
    """Whether a run stops on its coordinator's word, in either engine: the
    mission ended (c.done()), or with until="converged" the swarm converged.
    (A run also stops at its maxTicks.)"""
    return bool(c.done()) or (until == "converged" and c.converged_tick >= 0)


def run_outcome(c: Any) -> str:
    """The roster's outcome of an in-process run's coordinator: delivered,
    halted or stalled when it ended the mission, else stopped (maxTicks)."""
    from firmware_logic.roster import STOPPED
    return (c.ended() if has(c, Ending) else "") or STOPPED


class Engine:
    """Runs one scenario with one seed; `step()` advances one tick."""

    def __init__(self, sc: Scenario, seed: int, link: Link | None = None,
                 record_trajectories: bool = False, until: str = "delivered") -> None:
        if until not in UNTIL:
            raise ValueError(f"until: expected one of {UNTIL}, got {until!r}")
        self.until = until
        self.sc = sc
        self.seed = seed
        self.world = World(sc, seed)
        nodes = list(range(1, sc.agents + 1))
        self.link = link if link is not None else InprocLink(nodes)
        # the behaviour seam: robots and coordinator come from the registry
        self.behaviour = registry.load(sc.behaviour).activate()   # its message kinds in use
        self.robots = [self.behaviour.make_robot(n, seed, sc) for n in nodes]
        # any HAL: a mixed mission seats real bodies here (bridge/mission.py)
        self.bodies: list[Any] = [SimBody(self.world, i, n, self.link) for i, n in enumerate(nodes)]
        from perception import host_coordinator
        self.coordinator = host_coordinator(self.behaviour, sc, cells=list(self.world.object_cells))
        self.tick = 0
        self.record = record_trajectories
        self.trajectories: list[tuple[list[int], list[int]]] = []
        self.states: list[list[int]] = []
        # per-tick observers (sim_backend/observe.py): called with a Snapshot
        # after every tick; with none, no snapshot is built
        self.observers: list[Callable[[Any], None]] = []
        self.msgs_up = 0                 # messages the host received this tick
        self.msgs_down = 0               # messages (commands) it sent this tick
        self.bad_seen = 0                # the link's bad frames counted so far
        self.conv_steps = -1             # self.steps when the swarm converged
        # measures that watch the run through `observe` and add summary
        # fields and trace columns (COLUMNS, row()); none by default
        self.instruments: list[Any] = []

    def observe(self, fn: Callable[[Any], None]) -> None:
        """Call fn(snapshot) after every tick from now on."""
        self.observers.append(fn)

    def snapshot(self) -> Any:
        """The world and the host's view now (sim_backend/observe.py), every
        field built."""
        snap = self._snapshot()
        snap.freeze()
        return snap

    def _snapshot(self) -> Any:
        from sim_backend.observe import snapshot
        return snapshot(self)

    # -- one tick --------------------------------------------------------------

    def step(self) -> None:
        """One tick; under activation netlogo one go iteration (the kernel's
        turn loops, kernel.sync_tick and kernel.go_iteration)."""
        self.tick += 1
        w = self.world
        w.to_kernel(self.tick)
        if w.act == kernel.SEQUENTIAL:
            kernel.go_iteration(self.robots, self, w.grid, w.rb, w.run, 0)
        else:
            kernel.sync_tick(self.robots, self, w.grid, w.rb, w.run, 0)
        w.from_kernel()
        self.exchange()
        if self.conv_steps < 0 and self.coordinator.converged_tick >= 0:
            self.conv_steps = self.steps
        if self.observers:
            snap = self._snapshot()      # its fields built as observers read them
            alone = sys.getrefcount(snap)
            for fn in self.observers:
                fn(snap)
            # an observer that kept it (a view, an animation's last frame)
            # reads it after the next tick: its fields are this tick's
            if sys.getrefcount(snap) > alone:
                snap.freeze()
        if self.record:
            self.trajectories.append((list(self.world.xs), list(self.world.ys)))
            self.states.append([r.state for r in self.robots])

    def turn(self, robot: Any, i: int) -> None:
        """Robot i's FSM steps once on its body (the kernel's turn loops ask it)."""
        robot.step(self.bodies[i])

    @property
    def steps(self) -> int:
        """FSM steps of every robot so far (activation netlogo)."""
        return self.world.run.steps[0]

    def exchange(self) -> None:
        """This tick's messages to the coordinator, its commands to the link
        (sim_backend/exchange.py: the rule both engines follow)."""
        up = self.link.poll(0)
        down = exchange(self.coordinator, up, self.tick)
        assert down is not None          # asked every tick
        for node, kind, fields in down:
            self.link.send(node, kind, fields)
        self.msgs_up = len(up)
        self.msgs_down = len(down)

    def _apply(self) -> None:
        if self.world.act == kernel.SEQUENTIAL:
            # the seam real robots' tick ends use (bridge/mission.py, the
            # tether emulator): they act in parallel, so only sync applies
            raise EngineError("activation netlogo steps the robots one after another "
                              "inside the engine; a swarm with real or tethered robots runs "
                              "activation sync only")
        self.world.apply(self.tick)

    # -- a whole run -------------------------------------------------------------------

    def finished(self) -> bool:
        return run_ended(self.coordinator, self.until) or self.tick >= self.sc.maxTicks

    def run(self, progress: Callable[[int], None] | None = None) -> RunResult:
        while not self.finished():
            self.step()
            if progress is not None:
                progress(self.tick)
        return RunResult(self.sc, self.seed, self.tick, self.world, self.coordinator,
                         self.robots, self.trajectories, self.states, self.conv_steps,
                         self.instruments)


def run(sc: Scenario, seed: int, **kw) -> RunResult:
    return Engine(sc, seed, **kw).run()
