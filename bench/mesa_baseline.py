"""The soa engine against an independent per-agent Mesa 3 port of the thesis
model, robot-ticks per CPU second, both sides pinned to one core.

The Mesa model below is written from the thesis's Appendix A (the NetLogo
`go`, FindObject, LookForObject, RandomHead, HeadCarefully, FindField,
FollowField, Signal, Transport, DrawObject with object 1, the bar), not
from sim_backend/kernel.py: one `Robot(mesa.Agent)` per robot on a bounded
`mesa.space.MultiGrid` (-w..w), patch variables (colour, field) in plain
lists, the model's own `random`. Same world size, robots, object, home
(-15, -15), parameters (firefly, fieldDefiance 2, sigRadius 5, rPower 1,
objectWeight 5) and tick cap as the soa side. Two activations:

- sync (one action per robot per tick, as real robots act): every robot
  decides on the tick-start world (`agents.do("step")`), then claims and
  moves apply in node order (`agents.do("advance")`: a cell held at the
  tick's start or entered earlier this tick refuses a move, the first
  claimer of a segment wins); a robot in a field does its cycle
  (FollowField, then fieldDefiance RandomHeads) one step per tick;
- netlogo (`ask robots`: Mesa's `agents.shuffle_do("step")`, a fresh
  random order each tick, effects at once): a robot's turn is go's whole
  body, up to 1 + fieldDefiance moves.

After the holders' power reaches the weight (the converged tick) the object
and its holders move one patch a tick down the distance to home (Transport:
`downhill wayHome`) until a segment is within 4 of home (delivered).

Only live ticks count (a run's ticks until it delivered or hit the cap) on
both sides; set-up (model / engine construction) is counted in the
single-run case (what a user waits for) and apart elsewhere. The two
sides are stepped in turn over rounds in one process pinned to one core
(`os.sched_setaffinity`), so a busy neighbour slows both alike. The soa
step is loaded (or compiled, minutes, once per machine) before timing.

Prints one JSON: per case and activation, robot-ticks per CPU second of
each side and the ratio soa / Mesa, and the median converged tick of both
over seeds 1..20 (the check that the port is the same model, roughly). The
many-robot cases (1,000, 10,000 and 100,000 robots) also give the share of
the soa step spent in the compiled tick (the rest is the host's: messages
to the coordinators, their ticks, commands to the inboxes). A soa run holds
at most 20,000 robots, so its 100,000 are 10 runs of 10,000 in one batch
(one compiled call steps them all); Mesa's are one model on an arena of
the same robots per patch.

    .venv/bin/python bench/mesa_baseline.py [--quick] [--activation sync|netlogo|both] [--batch-runs N] [--sizes 10000,100000]

Mesa is a bench-only package (`make bench` installs it; not a runtime or
test dependency).
"""

from __future__ import annotations

import argparse
import gc
import json
import math
import os
import statistics
import sys
import time

os.environ.setdefault("OMP_NUM_THREADS", "1")
try:
    os.sched_setaffinity(0, {sorted(os.sched_getaffinity(0))[0]})
except (AttributeError, OSError):
    pass

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

try:
    import mesa
except ImportError:
    raise SystemExit("bench/mesa_baseline.py needs Mesa 3: .venv/bin/python -m pip install "
                     "'mesa>=3,<4' (make bench installs it)") from None

WHITE, YELLOW, BLUE = 0, 1, 2          # patch colours: free, object segment, held segment
HOME = (-15, -15)
PARAMS = {"fieldDefiance": 2, "sigRadius": 5, "rPower": 1.0, "objectWeight": 5.0}


class Robot(mesa.Agent):
    """robots-own [foundObject foundField isMobile isLeader], a heading, and
    (sync) the step of its field cycle and its intents for the tick."""

    def __init__(self, model: "Thesis") -> None:
        super().__init__(model)
        self.heading = 0.0
        self.found_object = False
        self.found_field = False
        self.mobile = True
        self.leader = False
        self.cycle = 0                  # sync: 0 FollowField, 1..fieldDefiance RandomHead
        self.move_to = None             # sync intents
        self.claim = None

    # -- the patch ahead and the primitives of Appendix A ---------------------------------

    def ahead(self) -> tuple[int, int]:
        h = math.radians(self.heading)
        x, y = self.pos
        return x + round(math.sin(h)), y + round(math.cos(h))

    def random_heading(self) -> None:
        self.heading = float(self.model.random.randrange(360))

    def head_carefully(self) -> None:
        """HeadCarefully: a robot, the object or a held segment ahead (or the
        arena's edge): a new random heading; else fd 1."""
        m = self.model
        c = self.ahead()
        if not m.inside(c) or m.color[c[0]][c[1]] != WHITE or not m.grid.is_cell_empty(c):
            self.random_heading()
        elif m.immediate:
            m.grid.move_agent(self, c)
        else:
            self.move_to = c

    def random_head(self) -> None:                  # firefly: RandomHead
        self.random_heading()
        self.head_carefully()

    def look_for_object(self) -> bool:
        m = self.model
        c = self.ahead()
        if m.inside(c) and m.color[c[0]][c[1]] == YELLOW:
            if m.immediate:
                m.claim(self, c)
            else:
                self.claim = c
            return True
        return False

    def find_object(self) -> None:                  # firefly: FindObject
        for h in (0, 90, 180, 270):
            if self.found_object or self.claim is not None:
                return
            self.heading = float(h)
            if not self.look_for_object():
                self.random_heading()

    def field_ahead(self) -> bool:
        c = self.ahead()
        return self.model.inside(c) and self.model.field[c[0]][c[1]] > 0

    def follow_field(self) -> None:                 # FollowField: heading uphill field
        m = self.model
        x, y = self.pos
        best, picks = None, []
        for dx, dy in m.NEIGHBOURS:
            c = (x + dx, y + dy)
            if m.inside(c):
                f = m.field[c[0]][c[1]]
                if best is None or f > best:
                    best, picks = f, [(dx, dy)]
                elif f == best:
                    picks.append((dx, dy))
        dx, dy = m.random.choice(picks)
        self.heading = math.degrees(math.atan2(dx, dy)) % 360
        self.head_carefully()

    # -- go's body ------------------------------------------------------------------------

    def step(self) -> None:
        m = self.model
        if m.immediate:                 # netlogo: go's whole body in the robot's turn
            if self.mobile and not self.found_object and not self.found_field:
                self.random_head()
                self.find_object()
                if not self.found_object and self.field_ahead():    # FindField
                    self.found_field = True
                    self.follow_field()
            if self.found_field and not self.found_object:
                self.follow_field()
                for _ in range(m.field_defiance):
                    self.random_head()
                self.find_object()
                if self.found_object:
                    return
            if not self.found_field and self.found_object:
                self.leader = True
                m.field[self.pos[0]][self.pos[1]] = 10
            return
        # sync: one action of the cycle, on the tick-start world
        self.move_to = self.claim = None
        if self.found_object:
            if not self.found_field:
                self.leader = True
                m.field[self.pos[0]][self.pos[1]] = 10
            return
        if not self.found_field:
            self.random_head()
            self.find_object()
            if self.claim is None and self.field_ahead():
                self.found_field = True
                self.cycle = 0
        else:
            if self.cycle == 0:
                self.follow_field()
            else:
                self.random_head()
            self.cycle = (self.cycle + 1) % (m.field_defiance + 1)
            if self.cycle == 0:
                self.find_object()

    def advance(self) -> None:
        """sync: this robot's claim, then its move, in node order."""
        m = self.model
        if self.claim is not None:
            c = self.claim
            if m.color[c[0]][c[1]] == YELLOW:
                m.claim(self, c)
        elif self.move_to is not None:
            c = self.move_to
            if c not in m.held_at_start and m.grid.is_cell_empty(c) \
                    and m.color[c[0]][c[1]] == WHITE:
                m.grid.move_agent(self, c)


class Thesis(mesa.Model):
    NEIGHBOURS = [(dx, dy) for dx in (-1, 0, 1) for dy in (-1, 0, 1) if dx or dy]

    def __init__(self, agents: int = 20, world: int = 18, seed: int = 1,
                 activation: str = "sync", max_ticks: int = 20000) -> None:
        super().__init__(seed=seed)
        self.w = world
        self.size = 2 * world + 1
        self.immediate = activation == "netlogo"
        self.field_defiance = PARAMS["fieldDefiance"]
        self.max_ticks = max_ticks
        self.grid = mesa.space.MultiGrid(self.size, self.size, torus=False)
        self.color = [[WHITE] * self.size for _ in range(self.size)]
        self.field = [[0] * self.size for _ in range(self.size)]
        self.home = (HOME[0] + world, HOME[1] + world)
        self.power = 0.0
        self.tick = 0
        self.converged_tick = -1
        self.delivered_tick = -1
        self.signals: list[tuple[int, int]] = []
        r = PARAMS["sigRadius"]
        self.stencil = [(dx, dy, int(10 / (1 + math.hypot(dx, dy)) + 0.5))
                        for dx in range(-r, r + 1) for dy in range(-r, r + 1)
                        if math.hypot(dx, dy) <= r]
        # CreateWorld: objx, objy = random 10; DrawObject, object 1 (the bar)
        ox, oy = self.random.randrange(10) + world, self.random.randrange(10) + world
        self.object = []
        for a in range(1, 9):
            for c in ((ox + a, oy), (ox + a, oy + 1)):
                self.color[c[0]][c[1]] = YELLOW
                self.object.append(c)
        # CreateSwarm: fd random max-pxcor from the centre, redrawn off the
        # object and other robots
        for _ in range(agents):
            rb = Robot(self)
            while True:
                rb.random_heading()
                d = self.random.randrange(world)
                h = math.radians(rb.heading)
                c = (world + round(d * math.sin(h)), world + round(d * math.cos(h)))
                if self.inside(c) and self.color[c[0]][c[1]] == WHITE \
                        and self.grid.is_cell_empty(c):
                    break
            self.grid.place_agent(rb, c)
            rb.random_heading()
        self.held_at_start: set = set()

    def inside(self, c: tuple[int, int]) -> bool:
        return 0 <= c[0] < self.size and 0 <= c[1] < self.size

    def claim(self, rb: Robot, c: tuple[int, int]) -> None:
        """LookForObject's success: the segment held, the robot still,
        SetLocation (its own patch) for Signal, its power counted."""
        self.color[c[0]][c[1]] = BLUE
        rb.found_object = True
        rb.mobile = False
        self.signals.append(rb.pos)
        self.power += PARAMS["rPower"]

    def signal(self, x: int, y: int) -> None:
        for dx, dy, v in self.stencil:
            c = (x + dx, y + dy)
            if self.inside(c):
                self.field[c[0]][c[1]] += v

    def transport(self) -> None:
        """Transport: the object and its holders one patch down the distance
        to home, until a segment is within 4 of it."""
        cells = [(x, y, self.color[x][y]) for x, y in self.object]
        holders = [rb for rb in self.agents if rb.found_object]
        spots = [c[:2] for c in cells] + [rb.pos for rb in holders]
        # downhill wayHome: the step that brings the object nearest home, of
        # those the arena allows
        steps = sorted(self.NEIGHBOURS, key=lambda d: self.way_home(d))
        for dx, dy in steps:
            if all(self.inside((x + dx, y + dy)) for x, y in spots):
                break
        else:
            return                      # hemmed in by the arena's edges
        for x, y, _ in cells:
            self.color[x][y] = WHITE
        self.object = [(x + dx, y + dy) for x, y, _ in cells]
        for x, y, col in cells:
            self.color[x + dx][y + dy] = col
        for rb in holders:
            x, y = rb.pos
            self.grid.move_agent(rb, (x + dx, y + dy))
        if self.way_home((0, 0)) < 4:
            self.delivered_tick = self.tick

    def way_home(self, d: tuple[int, int]) -> float:
        """wayHome of the object's segment nearest home, after a step d."""
        hx, hy = self.home
        return min(math.hypot(x + d[0] - hx, y + d[1] - hy) for x, y in self.object)

    def step(self) -> None:
        self.tick += 1
        if self.immediate:
            self.agents.shuffle_do("step")
        else:
            self.held_at_start = {a.pos for a in self.agents}
            self.agents.do("step")
            self.agents.do("advance")
        if self.signals:                 # go: if found [Signal locx locy]
            x, y = self.signals[-1] if self.immediate else (None, None)
            for p in ([(x, y)] if self.immediate else self.signals):
                self.signal(*p)
            self.signals = []
        if self.converged_tick < 0 and self.power >= PARAMS["objectWeight"]:
            self.converged_tick = self.tick
        elif self.converged_tick >= 0:
            self.transport()

    def live(self) -> bool:
        return self.delivered_tick < 0 and self.tick < self.max_ticks


# -- the soa side -------------------------------------------------------------------------

def soa_scenario(agents: int, world: int, activation: str, max_ticks: int):
    from sim_backend.scenario import validate
    return validate({"agents": agents, "worldSize": world, "activation": activation,
                     "maxTicks": max_ticks, **{k: v for k, v in PARAMS.items()}})


class Side:
    """One engine's CPU seconds and live robot-ticks over a case."""

    def __init__(self) -> None:
        self.cpu = 0.0
        self.robot_ticks = 0

    def rate(self) -> float:
        return self.robot_ticks / self.cpu if self.cpu else 0.0

    def mesa_run(self, agents, world, seed, act, max_ticks):
        """One Mesa run to its end, its CPU time and live robot-ticks counted here."""
        t = time.process_time()
        m = Thesis(agents, world, seed, act, max_ticks)
        while m.live():
            m.step()
        self.cpu += time.process_time() - t
        self.robot_ticks += agents * m.tick
        return m


def single_runs(agents, world, act, seeds, max_ticks, rounds):
    """Each run alone, built and stepped to the end (set-up counted): the
    seeds split into rounds, the sides in turn."""
    from sim_backend.batch.soa import SoaEngine
    sc = soa_scenario(agents, world, act, max_ticks)
    soa, mes = Side(), Side()
    conv = {"soa": [], "mesa": []}
    parts = [seeds[k::rounds] for k in range(rounds)]
    for k, part in enumerate(parts):
        order = ("soa", "mesa") if k % 2 == 0 else ("mesa", "soa")
        for side in order:
            for s in part:
                if side == "soa":
                    t = time.process_time()
                    r = SoaEngine([(sc, s)]).run()[0]
                    soa.cpu += time.process_time() - t
                    soa.robot_ticks += agents * r.ticks
                    conv["soa"].append(r.summary()["converged_tick"])
                else:
                    m = mes.mesa_run(agents, world, s, act, max_ticks)
                    conv["mesa"].append(m.converged_tick)
    return soa, mes, conv


def batch_runs(agents, world, act, soa_seeds, mesa_seeds, max_ticks, chunk_ticks=25):
    """soa: one batch of every run (a sweep's chunk), live robot-ticks only;
    Mesa: its runs one after another (a batch does not change a per-agent
    model's rate). In turn: one Mesa run, then chunk_ticks soa ticks."""
    from sim_backend.batch import body as B
    from sim_backend.batch.soa import SoaEngine
    sc = soa_scenario(agents, world, act, max_ticks)
    soa, mes = Side(), Side()
    t = time.process_time()
    eng = SoaEngine([(sc, s) for s in soa_seeds])
    setup = time.process_time() - t
    todo = list(mesa_seeds)
    while todo or not eng.finished():
        if todo:
            mes.mesa_run(agents, world, todo.pop(0), act, max_ticks)
        for _ in range(chunk_ticks):
            if eng.finished():
                break
            live = int(eng.rt[B.LIVE].sum())
            t = time.process_time()
            eng.step()
            soa.cpu += time.process_time() - t
            soa.robot_ticks += agents * live
    return soa, mes, setup


def big_run(agents, world, act, seed, ticks, rounds, runs=1, mesa_world=None):
    """Many robots on each side, set-up apart, live ticks (at most `ticks`)
    stepped in rounds, the sides in turn. soa: `runs` runs of `agents`
    robots in one batch (one compiled call steps them all; a run holds at
    most 20,000 robots); Mesa: one model of every robot (agents * runs) on
    `mesa_world` (the same robots per patch)."""
    from sim_backend.batch.soa import SoaEngine
    sc = soa_scenario(agents, world, act, ticks)
    eng = SoaEngine([(sc, seed + k) for k in range(runs)])
    eng.step()                                    # the first tick apart on both sides
    m = Thesis(agents * runs, mesa_world or world, seed, act, ticks)
    m.step()
    # Both sides share one heap: the collector's passes over objects built at
    # set-up (the Mesa model's agents, the soa robots' CPython objects) would
    # fall on whichever side allocates when one triggers; neither side's rate
    # should carry the other's heap
    gc.collect()
    gc.freeze()
    soa, mes = Side(), Side()
    compiled = [0.0]              # the soa step's CPU in the compiled tick (the rest: the host's)
    tick = eng._tick

    def timed_tick(t: int) -> None:
        c = time.process_time()
        tick(t)
        compiled[0] += time.process_time() - c
    eng._tick = timed_tick
    share = max(1, (ticks - 1) // rounds)
    k = 0
    while (not eng.finished()) or m.live():
        for side in (("soa", "mesa") if k % 2 == 0 else ("mesa", "soa")):
            for _ in range(share):
                if side == "soa" and not eng.finished():
                    t = time.process_time()
                    eng.step()
                    soa.cpu += time.process_time() - t
                    soa.robot_ticks += agents * runs
                elif side == "mesa" and m.live():
                    t = time.process_time()
                    m.step()
                    mes.cpu += time.process_time() - t
                    mes.robot_ticks += agents * runs
        k += 1
    gc.unfreeze()
    return soa, mes, {"soa_ticks": eng.tick, "mesa_ticks": m.tick,
                      "soa_compiled_share": round(compiled[0] / soa.cpu, 3) if soa.cpu else None}


def median(xs):
    got = [x for x in xs if x is not None and x >= 0]
    return statistics.median(got) if got else None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="fewer runs and ticks (a smoke)")
    ap.add_argument("--activation", choices=("sync", "netlogo", "both"), default="both")
    ap.add_argument("--batch-runs", type=int, default=None,
                    help="soa runs in the batch case (default: 500, 40 with --quick)")
    ap.add_argument("--sizes", default=None,
                    help="only these many-robot cases, e.g. 10000,100000 (and no small ones)")
    a = ap.parse_args()
    from sim_backend.batch.soa import SoaEngine
    acts = ("sync", "netlogo") if a.activation == "both" else (a.activation,)
    q = a.quick
    seeds = list(range(1, (6 if q else 20) + 1))
    batch_n, mesa_n = (40, 6) if q else (500, 60)
    if a.batch_runs is not None:
        batch_n = a.batch_runs
    # name: robots per soa run, worldSize, tick cap, soa runs, Mesa's worldSize
    big = {"1000": (1000, 40, 30 if q else 120, 1, 40),
           "10000": (10000, 150, 6 if q else 40, 1, 150),
           "100000": (10000, 150, 4 if q else 12, 10, 475)}
    if a.sizes:
        big = {k: v for k, v in big.items() if k in a.sizes.split(",")}
    out = {"clock": "process CPU seconds, one pinned core, both sides in turn",
           "mesa": mesa.__version__, "params": PARAMS, "cases": {}}
    for act in acts:
        SoaEngine([(soa_scenario(20, 18, act, 5), 1)]).run()     # load (or compile) the step
        cases = out["cases"].setdefault(act, {})
        if not a.sizes:
            s, m, conv = single_runs(20, 18, act, seeds, 20000, rounds=4)
            cases["20 robots, single runs"] = {
                "runs": len(seeds), "worldSize": 18, "setup": "counted",
                "soa": round(s.rate()), "mesa": round(m.rate()),
                "ratio": round(s.rate() / m.rate(), 2),
                "median_converged_tick": {"soa": median(conv["soa"]), "mesa": median(conv["mesa"])},
                "converged_runs": {k: sum(1 for x in v if x is not None and x >= 0)
                                   for k, v in conv.items()}}
            s, m, setup = batch_runs(20, 18, act, list(range(1, batch_n + 1)),
                                     list(range(1, mesa_n + 1)), 20000)
            cases[f"20 robots x {batch_n} runs"] = {
                "runs": {"soa": batch_n, "mesa": mesa_n}, "worldSize": 18,
                "soa_setup_s": round(setup, 3),
                "soa": round(s.rate()), "mesa": round(m.rate()), "ratio": round(s.rate() / m.rate(), 2)}
        for name, (agents, world, ticks, runs, mesa_world) in big.items():
            s, m, t = big_run(agents, world, act, 1, ticks, rounds=min(6, ticks - 1),
                              runs=runs, mesa_world=mesa_world)
            shape = {"worldSize": world} if runs == 1 else {
                "soa_shape": f"{runs} runs x {agents} robots, worldSize {world}, one batch",
                "mesa_shape": f"one model, worldSize {mesa_world}"}
            cases[f"{name} robots"] = {
                **shape, "tick_cap": ticks, **t, "setup": "apart",
                "soa": round(s.rate()), "mesa": round(m.rate()),
                "ratio": round(s.rate() / m.rate(), 2)}
    out["load_avg"] = os.getloadavg()
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
