"""What the live view shows, from one of two sources.

`SimSource` drives the reference engine itself: a runner thread steps it at
the page's chosen speed while playing and sleeps on a condition while
paused (no busy loop); `step` advances exactly the ticks asked for.
`JournalSource` follows a `touchswarm host` journal read-only: on each poll
it replays the journal into a fresh host coordinator (the host's own
`resume`), so touches, power, state and the perceived shape are what a
resumed host would hold; the behaviour's measures and reporters with their
titles, and its perceived shape and load only when it declares them
(sim_backend/words.py); poses and bad frames come from the journal's live
view (bridge/host/process.py writes it every LIVE_EVERY host ticks).

Both give the page the same JSON: `info()` once, `state()` on every poll.
"""

from __future__ import annotations

import logging
import threading
from pathlib import Path
from typing import Any

from bridge.errors import UsageError
from firmware_logic import messages as msg
from bridge.view import panels
from firmware_logic import perception

log = logging.getLogger(__name__)

EVENTS_SHOWN = 200        # the newest events the page gets
SPEED_MIN, SPEED_MAX = 1.0, 1000.0      # ticks per second while playing
STEP_MAX = 10000          # ticks one step request may ask for
BATCH_HZ = 50             # above this speed the runner steps several ticks per wake


class BadRequest(ValueError):
    """A control request the source refuses (the server answers 400)."""


def hex_colours(names: tuple[str, ...]) -> list[str]:
    """The states' colours as CSS hex, the same as every figure's."""
    from matplotlib.colors import to_hex
    from sim_backend.render import state_colours
    return [to_hex(c) for c in state_colours(names)]


def words_info(behaviour: Any) -> dict[str, Any]:
    """What the page is told once about the behaviour's words
    (sim_backend/words.py): its measures' and reporters' titles, whether it
    draws a perceived shape, and the words of its load bar (or none)."""
    from sim_backend import words
    w = words.of(behaviour)
    return {"behaviour": w.name, "measures": [list(m) for m in w.shown()],
            "shape": w.shape is not None, "load": list(w.load) if w.load else None}


def home_of(sc: Any, behaviour: Any) -> list[int] | None:
    """The scenario's home where the behaviour has one (spec.HOME,
    sim_backend/words.py), else None: the page then neither draws nor names it."""
    from sim_backend import words
    return [sc.homeX, sc.homeY] if words.of(behaviour).home else None


def coordinator_view(coord: Any, behaviour: Any, values: dict[str, Any] | None = None
                     ) -> dict[str, Any]:
    """What the page draws from the host coordinator: touches numbered in
    order where their segments are now, status, the behaviour's measures and
    reporters with their titles (`values`: the run's measures so far, when
    known; the coordinator's own measures and reporters are added), and only
    when the behaviour declares them the perceived shape (spec.SHAPE) and
    its load (spec.LOAD: e.g. power of weight, coordinator attributes in
    hundredths)."""
    from sim_backend import words
    from sim_backend.coordinator import Segmenting, measures_of
    w = words.of(behaviour)
    mx, my = getattr(coord, "moved_x", 0), getattr(coord, "moved_y", 0)
    touches = [{"n": i + 1, "node": t.node, "tick": t.tick,
                "rx": t.rx + mx, "ry": t.ry + my,
                "sx": getattr(t, "sx", t.rx) + mx, "sy": getattr(t, "sy", t.ry) + my}
               for i, t in enumerate(coord.touches)]
    values = {**(values or {}), **measures_of(coord),
              **behaviour.report(coord)}
    out = {"touches": touches, "status": coord.status(),
           "measures": words.shown_values(w, values),
           "found_tick": _tick_or_none(getattr(coord, "found_tick", -1)),
           "converged_tick": _tick_or_none(getattr(coord, "converged_tick", -1)),
           "home_tick": _tick_or_none(getattr(coord, "delivered_tick", -1)),
           "delivered": coord.delivered_tick >= 0}
    if w.shape is not None and isinstance(coord, Segmenting):
        out["perceived"] = [list(c) for c in
                            sorted(perception.outline_cells(coord.segments_now()))]
    if w.load is not None:
        for name in w.load:
            out[name] = getattr(coord, name) / 100
    return out


def load_text(behaviour: Any, coord: Any) -> str:
    """" (power 1 of 5)" after a touch event when the behaviour declares a load."""
    from sim_backend import words
    load = words.of(behaviour).load
    if load is None:
        return ""
    held, need = (getattr(coord, name) / 100 for name in load)
    return f" ({load[0]} {held:g} of {need:g})"


def _tick_or_none(t: int) -> int | None:
    return t if t >= 0 else None


def speed_value(body: dict[str, Any]) -> float:
    v = body.get("ticks_per_second")
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not SPEED_MIN <= v <= SPEED_MAX:
        raise BadRequest(f"speed: ticks_per_second must be a number {SPEED_MIN:g}..{SPEED_MAX:g}, "
                         f"got {v!r}")
    return float(v)


def step_count(body: dict[str, Any]) -> int:
    v = body.get("ticks", 1)
    if isinstance(v, bool) or not isinstance(v, int) or not 1 <= v <= STEP_MAX:
        raise BadRequest(f"step: ticks must be an integer 1..{STEP_MAX}, got {v!r}")
    return v


LAST_MESSAGES = 6        # a robot's newest messages the inspector shows


def watched_link(nodes: list[int], tick_of: Any) -> Any:
    """The in-process link, keeping each robot's newest LAST_MESSAGES
    messages, sent and received, for the robot inspector."""
    from collections import deque

    from sim_backend.engine import InprocLink

    class WatchedLink(InprocLink):
        def __init__(self) -> None:
            super().__init__(nodes)
            self.last: dict[int, deque] = {n: deque(maxlen=LAST_MESSAGES) for n in nodes}

        def robot_send(self, node: int, kind: int, fields: tuple) -> None:
            super().robot_send(node, kind, fields)
            self.last[node].append((tick_of(), "sent", kind, tuple(fields)))

        def send(self, node: int, kind: int, fields: tuple) -> None:
            super().send(node, kind, fields)
            for n in (self.last if node == 0 else (node,)):
                self.last[n].append((tick_of(), "received", kind, tuple(fields)))

    return WatchedLink()


def message_text(kind: int, fields: tuple, who: str = "") -> str:
    """"TOUCH from robot 3 (seq 1, ...)": a message's name, `who`, its fields."""
    name, layout = msg.SCHEMA[kind]
    return name + who + (" (" + ", ".join(f"{f[0]} {v}" for f, v in zip(layout, fields)) + ")"
                         if fields else "")


def robot_variables(robot: Any) -> dict[str, Any]:
    """A robot's own numbers (its timers, counters, modes), read off the
    object: whatever the behaviour's robot keeps as an int or a bool."""
    return {k: v for k, v in sorted(vars(robot).items())
            if not k.startswith("_") and isinstance(v, (int, bool))
            and k not in ("node", "state", "heading")}


class SimSource:
    kind = "sim"

    def __init__(self, sc: Any, seed: int, playing: bool = False, speed: float = 20.0) -> None:
        self.lock = threading.Condition()
        self.playing = playing
        self.speed = speed_value({"ticks_per_second": speed})
        self.closed = False
        self._setup(sc, seed)
        self.runner = threading.Thread(target=self._run, name="view-sim", daemon=True)
        self.runner.start()

    def _setup(self, sc: Any, seed: int) -> None:
        """A fresh engine for sc and seed (the start, and every reset)."""
        from sim_backend import words
        from sim_backend.engine import Engine
        self.sc = sc
        nodes = list(range(1, sc.agents + 1))
        self.engine: Engine = Engine(sc, seed, link=watched_link(nodes, lambda: self.engine.tick))
        from perception.tracker import attach
        attach(self.engine)     # the shape estimate and recognition, as `touchswarm run` has them
        self.bad_frames = 0
        self.events: list[str] = [f"tick 0: {sc.agents} robots, scenario {sc.name}, seed {seed}"]
        self._seen = {"touches": 0, "converged": False, "delivered": False}
        said = words.of(self.engine.behaviour)
        self.done_word = said.result[1]                 # e.g. DELIVERED
        # convergence is an event only for a behaviour that measures it
        self._seen["converged"] = "converged_tick" not in dict(said.measures)
        names = tuple(self.engine.behaviour.spec.STATES)
        self.plots = panels.plots(self.engine.behaviour, hex_colours(names),
                                  instruments=tuple(self.engine.instruments))
        self.history = panels.History()
        self.snap = self.engine.snapshot()
        self._sample(self.snap)
        self.engine.observe(self._observe)

    def _sample(self, snap: Any) -> None:
        self.history.add(snap.tick, {
            **panels.sample(self.engine.behaviour, self.engine.coordinator, snap.states,
                            snap.iou),
            **panels.instrument_values(tuple(self.engine.instruments))})

    # -- the engine's observer (called under the lock, inside step) ----------

    def _observe(self, snap: Any) -> None:
        self.snap = snap
        self._sample(snap)
        self.bad_frames += snap.bad_frames
        c = self.engine.coordinator
        for i in range(self._seen["touches"], len(c.touches)):
            self.events.append(f"tick {snap.tick}: touch {i + 1} by robot {c.touches[i].node}"
                               + load_text(self.engine.behaviour, c))
        self._seen["touches"] = len(c.touches)
        if getattr(c, "converged_tick", -1) >= 0 and not self._seen["converged"]:
            self._seen["converged"] = True
            self.events.append(f"tick {snap.tick}: converged, leader robot {c.leader}")
        if c.delivered_tick >= 0 and not self._seen["delivered"]:
            self._seen["delivered"] = True
            self.events.append(f"tick {snap.tick}: {self.done_word}")

    # -- the runner: steps while playing, waits while paused -----------------

    def _run(self) -> None:
        with self.lock:
            while not self.closed:
                if not self.playing or self.engine.finished():
                    self.lock.wait()
                    continue
                batch = max(1, int(self.speed // BATCH_HZ))
                for _ in range(batch):
                    if self.engine.finished():
                        break
                    self.engine.step()
                if self.engine.finished():
                    self.playing = False
                    self.events.append(f"tick {self.engine.tick}: run finished")
                # the lock is released while waiting: controls and polls get in
                self.lock.wait(batch / self.speed)

    def close(self) -> None:
        with self.lock:
            self.closed = True
            self.lock.notify_all()
        self.runner.join()

    # -- controls (POST /control/ACTION) ------------------------------------

    def control(self, action: str, body: dict[str, Any]) -> dict[str, Any]:
        with self.lock:
            if action == "play":
                self.playing = not self.engine.finished()
            elif action == "pause":
                self.playing = False
            elif action == "step":
                n = step_count(body)
                self.playing = False
                for _ in range(n):
                    if self.engine.finished():
                        break
                    self.engine.step()
            elif action == "speed":
                self.speed = speed_value(body)
            elif action == "reset":
                sc, seed = self._reset_args(body)
                self.playing = False
                self._setup(sc, seed)
            else:
                raise BadRequest(f"unknown control {action!r}; expected play, pause, step, "
                                 "speed or reset")
            self.lock.notify_all()
            return self._summary()

    def _reset_args(self, body: dict[str, Any]) -> tuple[Any, int]:
        """The scenario and seed a reset asks for: {"set": ["KEY=VALUE", ...],
        "seed": n}, read and checked as `--set` and `--seed` are, so a bad
        value is refused in the command line's own words."""
        from bridge.commands.run import parse_overrides
        from bridge.errors import UsageError
        from sim_backend import scenario
        from sim_backend.errors import SimError
        items = body.get("set", [])
        if not isinstance(items, list) or not all(isinstance(i, str) for i in items):
            raise BadRequest(f"reset: set must be a list of \"KEY=VALUE\" texts, got {items!r}")
        try:
            seed = scenario.check_seed(body.get("seed", self.engine.seed), "--seed")
            changes = parse_overrides(items)
            if "behaviour" in changes:
                raise UsageError("--set behaviour: the view's behaviour is fixed; restart "
                                 "`touchswarm view --behaviour NAME`")
            return (self.sc.replace(**changes) if changes else self.sc), seed
        except (UsageError, SimError) as err:      # SimError: BehaviourError too
            raise BadRequest(str(err)) from None

    def robot(self, node: int) -> dict[str, Any]:
        """What the inspector shows of one robot: state, pose, heading, its
        own numbers (timers, counters), its newest messages."""
        with self.lock:
            e = self.engine
            if not 1 <= node <= len(e.robots):
                raise BadRequest(f"robot: node must be 1..{len(e.robots)}, got {node}")
            r = e.robots[node - 1]
            names = tuple(e.behaviour.spec.STATES)
            s = self.snap
            return {"node": node, "tick": e.tick, "state": names[r.state],
                    "x": s.xs[node - 1], "y": s.ys[node - 1],
                    "heading": getattr(r, "heading", None),
                    "variables": robot_variables(r),
                    "messages": [{"tick": t, "way": way, "text": message_text(k, f)}
                                 for t, way, k, f in e.link.last[node]]}

    def _claimed(self) -> list[list[int]]:
        """[x, y, node] of every object cell a robot holds now."""
        w = self.engine.world
        # only cells of objects (the target, decoys) are held: look those up,
        # not every patch of a large arena
        out = []
        for x, y in [*w.object_cells, *w.decoy_cells]:
            if -w.w <= x <= w.w and -w.w <= y <= w.w and w.owner[w.idx(x, y)]:
                out.append([x, y, w.owner[w.idx(x, y)]])
        return out

    def _summary(self) -> dict[str, Any]:
        c = self.engine.coordinator
        out = {"tick": self.engine.tick, "playing": self.playing, "speed": self.speed,
               "finished": self.engine.finished(), "touches": len(c.touches),
               "delivered": c.delivered_tick >= 0}
        load = words_info(self.engine.behaviour)["load"]
        if load:
            out[load[0]] = getattr(c, load[0]) / 100
        return out

    def _values(self) -> dict[str, Any]:
        """The run's measures so far (its summary at this tick)."""
        from sim_backend.engine import RunResult
        e = self.engine
        return RunResult(e.sc, e.seed, e.tick, e.world, e.coordinator, e.robots,
                         instruments=e.instruments).summary()

    # -- what the page reads ------------------------------------------------------

    def info(self) -> dict[str, Any]:
        with self.lock:
            return self._info()

    def _info(self) -> dict[str, Any]:
        w = self.engine.world
        names = tuple(self.engine.behaviour.spec.STATES)
        from sim_backend import render
        return {"source": self.kind, "title": f"scenario {self.sc.name}, seed {self.engine.seed}",
                "world": w.w, "home": home_of(self.sc, self.engine.behaviour),
                "states": list(names), "colours": hex_colours(names), "controls": True,
                "seed": self.engine.seed, "params": panels.fields(self.sc),
                "object": bool(w.start_cells),
                "decoys": bool(w.decoy_cells), "obstacles": bool(w.obstacle_cells),
                "estimate": render.estimate_of(self.engine.instruments) is not None,
                "plots": self.plots, **words_info(self.engine.behaviour)}

    def state(self) -> dict[str, Any]:
        with self.lock:
            s = self.snap
            field = s.field()
            view = coordinator_view(self.engine.coordinator, self.engine.behaviour,
                                    self._values())
            out = {
                **self._summary(),
                **view,
                "robots": [{"node": i + 1, "x": x, "y": y, "state": st}
                           for i, (x, y, st) in enumerate(zip(s.xs, s.ys, s.states))],
                "object": [list(c) for c in s.object_cells],
                "decoys": [list(c) for c in self.engine.world.decoy_cells],
                "obstacles": [list(c) for c in self.engine.world.obstacle_cells],
                "field": {"n": int(field.shape[0]), "max": int(field.max()),
                          "cells": field.ravel().tolist()},
                **({"iou": s.iou} if "perceived" in view else {}),
                **self._estimate(),
                "bad_frames": {"link": self.bad_frames} if self.bad_frames else {},
                "events": self.events[-EVENTS_SHOWN:],
                "claimed": self._claimed(),
                "plots": self.history.columns(panels.series_keys(self.plots)),
            }
        return out


    def _estimate(self) -> dict[str, Any]:
        """The host's shape estimate where the object is now and its verdict,
        as world.png and the animation draw it (sim_backend/render.py); none
        when no perception measure watches the run."""
        from sim_backend import render
        view = render.estimate_of(self.engine.instruments)
        if view is None or not view[0]:
            return {}
        dx, dy = render.displacement(self.engine.world)
        return {"estimate": [[x + dx, y + dy] for x, y in sorted(view[0])],
                "verdict": render.verdict_text(view[1], view[2])}


class JournalSource:
    kind = "journal"

    def __init__(self, path: Path, sc: Any) -> None:
        from bridge.host.journal import Journal, JournalError
        if not path.exists():
            raise UsageError(f"--journal {path}: no such file")
        if not path.is_file():
            raise UsageError(f"--journal {path}: not a file")
        try:
            with Journal(path, readonly=True) as j:
                behaviour = j.behaviour()
                j.last_tick()
        except JournalError as err:
            raise UsageError(f"--journal {err}") from None
        # the journal names, never imports: a folder only when trusted
        from sim_backend import registry
        try:
            registry.named_by_data(behaviour, f"--journal {path}: its meta")
        except registry.BehaviourError as err:
            raise UsageError(str(err)) from None
        self.path = path
        # the behaviour the journal was written by, whatever the scenario says
        self.sc = sc.replace(behaviour=behaviour) if behaviour != sc.behaviour else sc
        self.lock = threading.Lock()
        self.cached: tuple[Any, dict[str, Any]] | None = None
        from sim_backend import registry
        self.behaviour = registry.load(self.sc.behaviour)
        names = tuple(self.behaviour.spec.STATES)
        # the host does not know the object: no shape score to plot
        self.plots = panels.plots(self.behaviour, hex_colours(names), shape=False)
        # robots per state by live-view tick, as the polls see it (the
        # journal keeps only the newest poses)
        self.state_rows: dict[int, dict[str, int]] = {}

    def close(self) -> None:
        pass

    def control(self, action: str, body: dict[str, Any]) -> dict[str, Any]:
        raise BadRequest(f"{action}: the journal source follows a host; it has no play, "
                         "pause, step or speed")

    def info(self) -> dict[str, Any]:
        from sim_backend import registry
        behaviour = registry.load(self.sc.behaviour)
        names = tuple(behaviour.spec.STATES)
        # the host knows neither the object's cells nor a perception estimate
        return {"source": self.kind, "title": f"host journal {self.path}",
                "world": self.sc.worldSize, "home": home_of(self.sc, behaviour),
                "states": list(names), "colours": hex_colours(names), "controls": False,
                "object": False, "estimate": False,
                "plots": self.plots, **words_info(behaviour)}

    def state(self) -> dict[str, Any]:
        from bridge.host.journal import Journal, JournalError
        try:
            with Journal(self.path, readonly=True) as j:
                entries, live = j.entries(), j.live()
                # the journal only grows: its length and the live view mark a change
                mark = (len(entries), live)
                with self.lock:
                    if self.cached is not None and self.cached[0] == mark:
                        return self.cached[1]
                out = self._read(j, entries, live)
        except JournalError as err:
            # the host may be mid-write or the file gone: show it, keep polling
            return {"source": self.kind, "error": str(err), "tick": 0, "touches": [],
                    "robots": [], "events": [str(err)]}
        with self.lock:
            self.cached = (mark, out)
        return out

    def _read(self, j: Any, entries: list[Any], live: dict[str, Any] | None) -> dict[str, Any]:
        from bridge.host.journal import Report
        from bridge.host.process import HostProcess
        host = HostProcess(None, self.sc.weight_centi, self.sc.homeX, self.sc.homeY,  # type: ignore[arg-type]
                           world_size=self.sc.worldSize, behaviour=self.sc.behaviour,
                           scenario=self.sc)
        samples: list[tuple[int, dict[str, Any]]] = []
        beh = self.behaviour
        host.resume(j, after=lambda e: samples.append((e.tick, panels.sample(beh, host.coord))))
        events: list[str] = []
        last_decision: list[Any] = [None, 0, 0]     # kind, first tick, repeats
        for e in entries:
            if isinstance(e, Report):
                last_decision[0] = None
                events.append(f"tick {e.tick}: "
                              + message_text(e.kind, e.fields, f" from robot {e.node}"))
            elif e.kind == last_decision[0]:
                # a decision repeated tick after tick (e.g. a halt) is one line
                last_decision[2] += 1
                events[-1] = (f"tick {last_decision[1]}: decision {e.kind} (repeated to tick "
                              f"{e.tick}, {last_decision[2]} times)")
            else:
                last_decision[:] = [e.kind, e.tick, 1]
                events.append(f"tick {e.tick}: decision {e.kind}")
        tick = max(host.tick, int(live["tick"]) if live else 0)
        robots = poses(live)
        halted = self._halted(host)
        if halted is not None:
            for r in robots:
                r["state"], r["halted"] = halted, True
        if live:
            counts = panels.sample(beh, host.coord, tuple(r["state"] for r in robots))
            self.state_rows[int(live["tick"])] = {k: v for k, v in counts.items()
                                                  if k.startswith("state:")}
        samples += list(self.state_rows.items())
        samples.sort(key=lambda ts: ts[0])
        history = panels.History()
        for t, values in samples:
            history.add(t, values)
        return {"tick": tick, "playing": False, "finished": host.coord.done(),
                **coordinator_view(host.coord, beh),
                "robots": robots, "object": None, "field": None,
                "bad_frames": (live or {}).get("bad_frames", {}),
                "live": live is not None,
                "events": events[-EVENTS_SHOWN:],
                "plots": history.columns(panels.series_keys(self.plots))}

    def _halted(self, host: Any) -> int | None:
        """The behaviour's halt state (spec.HALT) once the host is done and has
        sent HALT: every robot is then drawn halted, whatever its last
        HEARTBEAT said (it stops and may fall silent)."""
        code = getattr(self.behaviour.spec, "HALT", None)
        if code is None or not host.coord.done() or host.halts_sent == 0:
            return None
        return code


def poses(live: dict[str, Any] | None) -> list[dict[str, Any]]:
    """Robots from the live view's last HEARTBEATs, positions in patches."""
    if not live:
        return []
    layout = msg.spec(msg.HEARTBEAT)[4]
    names = [f[0] for f in layout]
    scale = {f[0]: f[3] for f in layout}      # a field's divisor: raw / divisor = patches
    out = []
    for node, p in sorted(live.get("poses", {}).items(), key=lambda kv: int(kv[0])):
        f = dict(zip(names, p[1:]))
        out.append({"node": int(node), "x": f["x"] / scale["x"], "y": f["y"] / scale["y"],
                    "state": f["state"], "heard_tick": p[0]})
    return out
