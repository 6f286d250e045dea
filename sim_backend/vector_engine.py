"""The vectorised tick engine: many runs x many robots in numpy arrays.

It implements exactly the tick semantics of the reference engine
(sim_backend/engine.py, docs/tick-semantics.md) and is bit-identical to it
for every seed: every robot's MWC RNG lanes live in int64 arrays and advance
only where the firmware FSM (firmware_logic/behaviours/thesis/robot.py) would draw, so robots
that draw a data-dependent number of values per tick (firefly FindObject
after each failed probe, HeadCarefully only when blocked) stay in step with
the reference. Sensing reads the tick-start snapshot; intents are applied in
the reference's order (claims lowest node first, beacons, the carried group,
moves in node order with the 'entered' rule, resolved with np.unique on
destination cells, whose first occurrence is the lowest node).

All robots of all runs sit in one flat set of arrays, run-major and in node
order within a run; the runs' grids are one flat array with a fixed stride
per run. The host coordinator stays per-run Python
(firmware_logic.behaviours.thesis.coordinator.Coordinator), fed the same messages in the same
order as the in-process link feeds it; it is only called for a run that
received a message this tick or is in the centralised phase (every other
call would return nothing and change nothing).

A run stops when it is delivered (or, with ``until="converged"``, when power
first reaches the weight) or at its scenario's maxTicks, exactly where the
reference's ``Engine.run`` stops; its robots are frozen and the arrays are
compacted once enough runs have stopped.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Iterable, Sequence

import numpy as np

from firmware_logic import fixedpoint as fx
from firmware_logic import messages as msg
from firmware_logic import rng as _rng
from firmware_logic import registry
from firmware_logic.behaviours.thesis.coordinator import Coordinator
from firmware_logic.behaviours.thesis.robot import (ANT, CARRY, FIELD, FIREFLY, GRASP, HALT, HEARTBEAT_EVERY,
                                  HOLD, RETX_FIRST, RETX_MAX, SEARCH)
from sim_backend.engine import RunResult
from sim_backend.errors import EngineError
from sim_backend.scenario import Scenario, arena_features, departures, extensions
from sim_backend import kernel
from sim_backend.world import BLUE, FREE, YELLOW, World, signal_table

DEAD = 7          # a robot of a run that has stopped: inert until compacted
UNTIL = ("delivered", "converged")

_SIN = np.array(fx.SIN14, dtype=np.int64)
_COS = np.array([fx.SIN14[(h + 90) % 360] for h in range(360)], dtype=np.int64)
_DX1 = np.array([fx.dx(h, fx.ONE) for h in range(360)], dtype=np.int64)
_DY1 = np.array([fx.dy(h, fx.ONE) for h in range(360)], dtype=np.int64)
_UPHILL = ((0, 0, 1), (45, 1, 1), (90, 1, 0), (135, 1, -1),
           (180, 0, -1), (225, -1, -1), (270, -1, 0), (315, -1, 1))
_M15 = 0x7FFF
_A1 = np.int64(_rng.A1)
_A2 = np.int64(_rng.A2)
_EMPTY = np.zeros(0, dtype=np.int64)

# per-robot arrays that follow the robots through compaction
_ROBOT_FIELDS = (
    "rid", "node", "x", "y", "lx", "ly", "heading", "state", "resume", "phase", "first",
    "claim_heading", "seq", "pending", "retx_timer", "retx_every", "rx", "ry", "sx", "sy",
    "hello_acked", "last_step", "done_step", "cdx", "cdy", "carry_due",
    "model", "span", "defiance", "power", "step_len", "wr", "held",
    "has_carry", "cix", "ciy", "beacon_on", "bsx", "bsy", "announced", "sig",
)


@dataclass
class _ObjCells:
    """What RunResult.summary() reads of a world: the object's cells now."""
    object_cells: list


def _seed_lanes(seed: np.ndarray, node: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Vectorised firmware_logic.rng.Rng(seed, node): seed_state, then 8 discards."""
    s = (seed % 1000003) * 7919 + (node % 65521) * 104729 + 12345
    x = s % (_rng.M1 - 1) + 1
    y = (s * 31 + 977) % (_rng.M2 - 1) + 1
    for _ in range(8):
        x = _A1 * (x & _M15) + (x >> 15)
        y = _A2 * (y & _M15) + (y >> 15)
    return x, y


class VectorEngine:
    """A batch of independent runs (scenario, seed) stepped together."""

    def __init__(self, runs: Sequence[tuple[Scenario, int]], record_trajectories: bool = False,
                 until: str = "delivered") -> None:
        if until not in UNTIL:
            raise ValueError(f"until: expected one of {UNTIL}, got {until!r}")
        self.until = until
        other = sorted({str(sc.behaviour) for sc, _ in runs} - {"thesis"})
        if other:
            # a hand-written specialisation of one behaviour: never run another's scenario
            raise EngineError(f"the vector engine runs the thesis behaviour only, not "
                              f"{', '.join(other)}; use the batch engine")
        feats = sorted({k for sc, _ in runs for k in arena_features(sc)})
        if feats:
            # a hand copy of the thesis's one-object open arena; the batch engine runs the rest
            raise EngineError(f"the vector engine runs one object in an open arena with the "
                              f"static field only, not {', '.join(feats)}; use the batch engine")
        opts = sorted({k for sc, _ in runs for k in departures(sc) + extensions(sc)})
        if opts:
            # a hand copy of the default rules only; the batch engine runs the options
            raise EngineError(f"the vector engine runs the default rules only, not "
                              f"{', '.join(opts)}; use the batch engine")
        self.record = record_trajectories
        self.tick = 0
        self.runs = list(runs)
        nr = len(self.runs)
        self.wmax = max(sc.worldSize for sc, _ in self.runs) if nr else 1
        self.nn = 2 * self.wmax + 1
        self.stride = self.nn * self.nn
        # per run (indexed by run id, never compacted)
        self.coords: list[Coordinator] = []
        self.cells: list[list[tuple[int, int]]] = []
        self.results: list[RunResult | None] = [None] * nr
        self.max_ticks = np.array([sc.maxTicks for sc, _ in self.runs], dtype=np.int64)
        self.c_leader = np.zeros(nr, dtype=np.int64)
        self.c_step = np.zeros(nr, dtype=np.int64)
        self.c_conv = np.zeros(nr, dtype=bool)
        # per slot (a live run's position in the grids): run ids, in order
        self.slot_run = np.arange(nr, dtype=np.int64)
        self.run_slot = np.arange(nr, dtype=np.int64)      # run id -> slot (-1 gone)
        self.run_start = np.zeros(nr, dtype=np.int64)      # run id -> first robot index
        self.alive = np.ones(nr, dtype=bool)
        self.dead_robots = 0
        self.inbox: list[tuple[int, int, tuple]] = []       # (robot index, kind, fields)
        self.frames: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self._tables: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        self._build()

    # -- set-up ---------------------------------------------------------------------

    def _build(self) -> None:
        nn, stride = self.nn, self.stride
        nr = len(self.runs)
        self.obj = np.zeros(nr * stride, dtype=np.int8)
        self.owner = np.zeros(nr * stride, dtype=np.int64)
        self.field = np.zeros(nr * stride, dtype=np.int64)
        self.occ = np.zeros(nr * stride, dtype=np.int64)
        cols: dict[str, list] = {k: [] for k in ("rid", "node", "x", "y", "seed", "model", "span",
                                                 "defiance", "power", "wr", "sig")}
        start = 0
        for r, (sc, seed) in enumerate(self.runs):
            w = World(sc, seed)
            self.coords.append(registry.load("thesis").coordinator(sc, cells=list(w.object_cells)))
            self.cells.append(list(w.object_cells))
            base = r * stride
            for (cx, cy) in w.object_cells:
                self.obj[base + (cy + sc.worldSize) * nn + cx + sc.worldSize] = YELLOW
            n = sc.agents
            self.run_start[r] = start
            start += n
            cols["rid"].append(np.full(n, r))
            cols["node"].append(np.arange(1, n + 1))
            cols["x"].append(np.array(w.xs))
            cols["y"].append(np.array(w.ys))
            cols["seed"].append(np.full(n, seed))
            cols["model"].append(np.full(n, sc.model))
            cols["span"].append(np.full(n, sc.robotVisionSpan))
            cols["defiance"].append(np.full(n, sc.fieldDefiance))
            cols["power"].append(np.full(n, sc.power_centi))
            cols["wr"].append(np.full(n, sc.worldSize))
            cols["sig"].append(np.full(n, sc.sigRadius))
        cat = {k: (np.concatenate(v).astype(np.int64) if v else _EMPTY.copy())
               for k, v in cols.items()}
        for k in ("rid", "node", "x", "y", "model", "span", "defiance", "power", "wr", "sig"):
            setattr(self, k, cat[k])
        n = len(self.node)
        self.lx, self.ly = _seed_lanes(cat["seed"], self.node)
        self.heading = _EMPTY.copy()
        z = lambda v=0: np.full(n, v, dtype=np.int64)  # noqa: E731
        self.heading = self._draw(np.arange(n), 360) if n else z()
        self.state = z(SEARCH)
        self.resume = z(SEARCH)
        for k in ("phase", "first", "claim_heading", "seq", "pending", "rx", "ry", "sx", "sy",
                  "hello_acked", "last_step", "done_step", "cdx", "cdy", "carry_due",
                  "has_carry", "cix", "ciy", "beacon_on", "bsx", "bsy", "announced"):
            setattr(self, k, z())
        self.retx_timer = z()
        self.retx_every = z(RETX_FIRST)
        self.step_len = np.where(self.model == FIREFLY, fx.ONE, fx.QUARTER).astype(np.int64)
        self.held = z(-1)
        self._index()
        np.add.at(self.occ, self.cell, 1)

    def _index(self) -> None:
        """Derived per-robot arrays that depend on slots."""
        self.base = self.run_slot[self.rid] * self.stride
        self.opx = (self.x + 128) >> 8
        self.opy = (self.y + 128) >> 8
        self.cell = self.base + (self.opy + self.wr) * self.nn + self.opx + self.wr

    # -- helpers ----------------------------------------------------------------------

    def _draw(self, g: np.ndarray, n) -> np.ndarray:
        """rng.below(n) (n > 0) for the robots g, advancing only their lanes."""
        x = self.lx[g]
        y = self.ly[g]
        x = _A1 * (x & _M15) + (x >> 15)
        y = _A2 * (y & _M15) + (y >> 15)
        self.lx[g] = x
        self.ly[g] = y
        return (((x & _M15) << 15) | (y & _M15)) % n

    def _ahead(self, g: np.ndarray, h) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(inside, flat cell (0 where outside), same-patch) one patch ahead."""
        px = (self.x[g] + _DX1[h] + 128) >> 8
        py = (self.y[g] + _DY1[h] + 128) >> 8
        w = self.wr[g]
        ins = (px >= -w) & (px <= w) & (py >= -w) & (py <= w)
        k = np.where(ins, self.base[g] + (py + w) * self.nn + px + w, 0)
        same = (px == self.opx[g]) & (py == self.opy[g])
        return ins, k, same

    def _is_object(self, g, h) -> tuple[np.ndarray, np.ndarray]:
        ins, k, _ = self._ahead(g, h)
        return ins & (self.obj[k] == YELLOW), k

    def _blocked(self, g, h) -> np.ndarray:
        """probe(h) != NOTHING."""
        ins, k, same = self._ahead(g, h)
        n = self.occ[k] - same
        return ~ins | (self.obj[k] != FREE) | (n > 0)

    def _uphill(self, g: np.ndarray) -> np.ndarray:
        px = self.opx[g]
        py = self.opy[g]
        w = self.wr[g]
        b = self.base[g]
        best = self.field[self.cell[g]]
        out = np.full(len(g), -1, dtype=np.int64)
        for h, ddx, ddy in _UPHILL:
            qx = px + ddx
            qy = py + ddy
            ins = (qx >= -w) & (qx <= w) & (qy >= -w) & (qy <= w)
            v = self.field[np.where(ins, b + (qy + w) * self.nn + qx + w, 0)]
            up = ins & (v > best)
            best = np.where(up, v, best)
            out = np.where(up, h, out)
        return out

    def _look(self, g: np.ndarray, h, k: np.ndarray) -> None:
        """LookForObject after a probe found OBJECT: claim and grasp."""
        self.claim_cell[g] = k
        self.heading[g] = h
        self.claim_heading[g] = h
        s = self.state[g]
        self.resume[g] = s
        self.first[g] |= (s == SEARCH)
        self.state[g] = GRASP

    def _table(self, radius: int):
        t = self._tables.get(radius)
        if t is None:
            rows = signal_table(radius)
            t = tuple(np.array([r[i] for r in rows], dtype=np.int64) for i in range(3))
            self._tables[radius] = t
        return t

    def _signal(self, g: np.ndarray, sign: int) -> None:
        sig = self.sig[g]
        for radius in np.unique(sig):
            gg = g[sig == radius]
            tdx, tdy, tv = self._table(int(radius))
            px = self.bsx[gg][:, None] + tdx[None, :]
            py = self.bsy[gg][:, None] + tdy[None, :]
            w = self.wr[gg][:, None]
            ins = (px >= -w) & (px <= w) & (py >= -w) & (py <= w)
            k = self.base[gg][:, None] + (py + w) * self.nn + px + w
            v = np.broadcast_to(tv[None, :], k.shape)
            np.add.at(self.field, k[ins], sign * v[ins])

    # -- one tick ---------------------------------------------------------------------------

    def step(self) -> None:
        self.tick += 1
        t = self.tick
        n = len(self.node)
        self.move_h = np.full(n, -1, dtype=np.int64)
        self.claim_cell = np.full(n, -1, dtype=np.int64)
        self.beacon_set = np.full(n, -1, dtype=np.int64)
        self._deliver()
        sends: list[tuple] = []
        self._decide(sends)
        self._housekeeping(t, sends)
        self._apply()
        self._exchange(t, sends)
        if self.record:
            self.frames.append((self.x.copy(), self.y.copy(), self.run_start.copy()))
        self._finish(t)

    def _deliver(self) -> None:
        """Each robot reads its inbox (firmware Robot._on_message), in order."""
        if not self.inbox:
            return
        st = self.state
        for g, kind, f in self.inbox:
            if kind == msg.ACK:
                if f[0] == 0:
                    self.hello_acked[g] = 1
                elif self.pending[g] and f[0] == self.seq[g]:
                    self.pending[g] = 0
            elif kind == msg.TRANSPORT:
                if st[g] == HOLD or st[g] == CARRY:
                    if f[0] != self.last_step[g]:
                        st[g] = CARRY
                        self.last_step[g] = f[0]
                        self.cdx[g] = f[1]
                        self.cdy[g] = f[2]
                        self.carry_due[g] = 1
            elif kind == msg.HALT:
                if st[g] != HALT and st[g] != DEAD:
                    st[g] = HALT
                    self.beacon_set[g] = 0
        self.inbox = []

    def _decide(self, sends: list) -> None:
        S = self.state.copy()
        P = self.phase.copy()
        model = self.model
        is_search = S == SEARCH
        is_field = S == FIELD
        fo = np.flatnonzero(is_search | (is_field & (P == 0)))
        # FindObject
        found = np.zeros(len(S), dtype=bool)
        if len(fo):
            fm = model[fo]
            act = fo[fm == FIREFLY]
            for h in (0, 90, 180, 270):
                if not len(act):
                    break
                hit, k = self._is_object(act, h)
                if hit.any():
                    gh = act[hit]
                    self._look(gh, h, k[hit])
                    found[gh] = True
                    act = act[~hit]
                if len(act):
                    self.heading[act] = self._draw(act, 360)
            ants = fo[fm == ANT]
            if len(ants):
                r = self._draw(ants, 100)
                span = self.span[ants]
                d = np.zeros(len(ants), dtype=np.int64)
                pos = span > 0
                if pos.any():
                    d[pos] = self._draw(ants[pos], span[pos])
                hd = self.heading[ants]
                self.heading[ants] = np.where(r % 2 == 0, hd + d, hd - d) % 360
                hd = self.heading[ants]
                hit, k = self._is_object(ants, hd)
                if hit.any():
                    gh = ants[hit]
                    self._look(gh, hd[hit], k[hit])
                    found[gh] = True
        # FindField (SEARCH), FollowField (FIELD, phase 0)
        sr = np.flatnonzero(is_search & ~found)
        if len(sr):
            ins, k, _ = self._ahead(sr, self.heading[sr])
            fa = ins & (self.field[k] > 0)
            sf = sr[fa]
            srh = sr[~fa]
        else:
            sf = srh = _EMPTY
        f0r = np.flatnonzero(is_field & (P == 0) & ~found)
        ff = np.concatenate((sf, f0r))
        if len(ff):
            u = self._uphill(ff)
            self.heading[ff] = np.where(u >= 0, u, self.heading[ff])
        if len(sf):
            self.state[sf] = FIELD
            self.phase[sf] = (self.defiance[sf] > 0).astype(np.int64)
        if len(f0r):
            self.phase[f0r] = (self.defiance[f0r] > 0).astype(np.int64)
        # RandomHead (SEARCH without a field; FIELD, phase > 0)
        fr = np.flatnonzero(is_field & (P > 0))
        rh = np.concatenate((srh, fr))
        if len(rh):
            rf = rh[model[rh] == FIREFLY]
            if len(rf):
                self.heading[rf] = self._draw(rf, 360)
        if len(fr):
            p = P[fr] + 1
            self.phase[fr] = np.where(p > self.defiance[fr], 0, p)
        # HeadCarefully for everyone who followed the field or headed randomly
        hc = np.concatenate((ff, rh))
        if len(hc):
            hd = self.heading[hc]
            bl = self._blocked(hc, hd)
            b = hc[bl]
            if len(b):
                self.heading[b] = self._draw(b, 360)
            mv = hc[~bl]
            self.move_h[mv] = hd[~bl]
        # GRASP: confirm the grip or resume
        gr = np.flatnonzero(S == GRASP)
        if len(gr):
            held = self.held[gr]
            ok = (held >= 0) & (self.owner[np.maximum(held, 0)] == self.node[gr])
            fail = gr[~ok]
            self.state[fail] = self.resume[fail]
            self.phase[fail] = 0
            g = gr[ok]
            if len(g):
                self.state[g] = HOLD
                self.beacon_set[g] = 1
                self.rx[g] = self.opx[g]
                self.ry[g] = self.opy[g]
                ch = self.claim_heading[g]
                self.sx[g] = (self.x[g] + _DX1[ch] + 128) >> 8
                self.sy[g] = (self.y[g] + _DY1[ch] + 128) >> 8
                s = self.seq[g] + 1
                self.seq[g] = np.where(s > 255, 1, s)
                self.pending[g] = 1
                self.retx_every[g] = RETX_FIRST
                sends.append((g, 0, msg.TOUCH, self._touch_fields(g)))
                self.retx_timer[g] = self.retx_every[g]
        # CARRY: report the pose, then execute a due transport step
        ca = np.flatnonzero(S == CARRY)
        if len(ca):
            sends.append((ca, 0, msg.HEARTBEAT, self._beat_fields(ca)))
            due = ca[self.carry_due[ca] == 1]
            if len(due):
                self.carry_due[due] = 0
                self.has_carry[due] = 1
                self.cix[due] = self.cdx[due]
                self.ciy[due] = self.cdy[due]
                self.done_step[due] = self.last_step[due]

    def _touch_fields(self, g):
        return (self.seq[g], self.rx[g], self.ry[g], self.sx[g], self.sy[g], self.power[g])

    def _beat_fields(self, g):
        return (self.state[g], self.x[g], self.y[g], self.heading[g], self.done_step[g])

    def _housekeeping(self, t: int, sends: list) -> None:
        if t % RETX_FIRST == 1:
            g = np.flatnonzero(self.hello_acked == 0)
            if len(g):
                sends.append((g, 1, msg.HELLO, (self.model[g], self.power[g],
                                                np.full(len(g), msg.FIRMWARE_VERSION))))
        p = np.flatnonzero(self.pending == 1)
        if len(p):
            self.retx_timer[p] -= 1
            due = p[self.retx_timer[p] <= 0]
            if len(due):
                self.retx_every[due] = np.minimum(self.retx_every[due] * 2, RETX_MAX)
                sends.append((due, 2, msg.TOUCH, self._touch_fields(due)))
                self.retx_timer[due] = self.retx_every[due]
        if t % HEARTBEAT_EVERY == 0:
            g = np.flatnonzero((self.state != CARRY) & (self.state != DEAD))
            if len(g):
                sends.append((g, 3, msg.HEARTBEAT, self._beat_fields(g)))

    # -- apply -------------------------------------------------------------------------------

    def _apply(self) -> None:
        obj = self.obj
        # claims: the lowest node claiming a still-yellow segment wins it
        c = np.flatnonzero(self.claim_cell >= 0)
        if len(c):
            k = self.claim_cell[c]
            yl = obj[k] == YELLOW
            c, k = c[yl], k[yl]
            if len(c):
                ku, first = np.unique(k, return_index=True)
                win = c[first]
                obj[ku] = BLUE
                self.owner[ku] = self.node[win]
                self.held[win] = ku
        # beacons
        on = np.flatnonzero((self.beacon_set == 1) & (self.beacon_on == 0))
        if len(on):
            self.beacon_on[on] = 1
            self.bsx[on] = self.opx[on]
            self.bsy[on] = self.opy[on]
            self._signal(on, 1)
        off = np.flatnonzero((self.beacon_set == 0) & (self.beacon_on == 1))
        if len(off):
            self.beacon_on[off] = 0
            self._signal(off, -1)
        entered = self._carry_groups()
        # moves, in node order
        m = np.flatnonzero(self.move_h >= 0)
        if len(m):
            h = self.move_h[m]
            st = self.step_len[m]
            nx = self.x[m] + ((_SIN[h] * st + 8192) >> 14)
            ny = self.y[m] + ((_COS[h] * st + 8192) >> 14)
            px = (nx + 128) >> 8
            py = (ny + 128) >> 8
            # from where the robot stands now: a robot that stepped aside for
            # the carried object (crowd "yield") moves on from its new patch
            same = (px == (self.x[m] + 128) >> 8) & (py == (self.y[m] + 128) >> 8)
            w = self.wr[m]
            ins = (px >= -w) & (px <= w) & (py >= -w) & (py <= w)
            k = np.where(ins, self.base[m] + (py + w) * self.nn + px + w, 0)
            cand = ~same & ins & (obj[k] == FREE) & (self.occ[k] == 0)
            if entered is not None:
                cand &= ~np.isin(k, entered)
            ok = same.copy()
            ci = np.flatnonzero(cand)
            if len(ci):
                _, first = np.unique(k[ci], return_index=True)
                ok[ci[first]] = True
            g = m[ok]
            self.x[g] = nx[ok]
            self.y[g] = ny[ok]
        self._recount()

    def _recount(self) -> None:
        old = self.cell
        self.opx = (self.x + 128) >> 8
        self.opy = (self.y + 128) >> 8
        new = self.base + (self.opy + self.wr) * self.nn + self.opx + self.wr
        ch = np.flatnonzero(old != new)
        if len(ch):
            np.subtract.at(self.occ, old[ch], 1)
            np.add.at(self.occ, new[ch], 1)
        self.cell = new

    def _carry_groups(self) -> np.ndarray | None:
        """Engine._carry_group for every run where some robot has a carry intent."""
        cand = np.flatnonzero(self.has_carry)
        if not len(cand):
            return None
        entered: list[int] = []
        nn = self.nn
        for r in np.unique(self.rid[cand]).tolist():
            lo = int(self.run_start[r])
            sc = self.runs[r][0]
            hi = lo + sc.agents
            hold = lo + np.flatnonzero(self.held[lo:hi] >= 0)
            if not len(hold) or not self.has_carry[hold].all():
                continue
            intents = {(int(a), int(b)) for a, b in zip(self.cix[hold], self.ciy[hold])}
            if len(intents) != 1:
                continue
            ddx, ddy = intents.pop()
            self.has_carry[hold] = 0                 # consumed, moved or blocked
            w = sc.worldSize
            base = int(self.run_slot[r]) * self.stride

            def idx(px, py):
                return base + (py + w) * nn + px + w

            hold_idx = {int(k) for k in self.cell[hold]}
            cells = self.cells[r]
            robots_at = list(zip(self.opx[hold].tolist(), self.opy[hold].tolist()))
            crowd = sc.crowd == "yield"
            blocked = False
            for x, y in cells + robots_at:
                nx, ny = x + ddx, y + ddy
                if not (-w <= nx <= w and -w <= ny <= w):
                    blocked = True
                    break
                k = idx(nx, ny)
                if not crowd and self.occ[k] > 0 and k not in hold_idx:
                    blocked = True
                    break
            if blocked or (crowd and not self._make_way(r, lo, hi, hold, ddx, ddy, entered)):
                continue
            ks = [idx(x, y) for x, y in cells]
            old_o = self.obj[ks].copy()
            old_w = self.owner[ks].copy()
            self.obj[ks] = FREE
            self.owner[ks] = 0
            moved = [(x + ddx, y + ddy) for x, y in cells]
            self.cells[r] = moved
            nk = [idx(x, y) for x, y in moved]
            self.obj[nk] = old_o
            self.owner[nk] = old_w
            self.x[hold] += ddx * fx.ONE
            self.y[hold] += ddy * fx.ONE
            self.held[hold] += ddy * nn + ddx
            px = (self.x[hold] + 128) >> 8
            py = (self.y[hold] + 128) >> 8
            entered.extend((base + (py + w) * nn + px + w).tolist())
            entered.extend(nk)
        return np.array(entered, dtype=np.int64) if entered else None

    def _make_way(self, r: int, lo: int, hi: int, hold: np.ndarray, ddx: int, ddy: int,
                  entered: list[int]) -> bool:
        """crowd "yield": kernel.make_way for run r, on the robots it reads
        (the carriers and the robots within kernel.CHAIN_DEPTH patches of the
        group's way, in node order; no other robot moves or is read, so the
        result is the kernel's); the patches they step to join `entered`."""
        sc = self.runs[r][0]
        w, nn = sc.worldSize, self.nn
        base = int(self.run_slot[r]) * self.stride
        way = {(x + ddx, y + ddy) for x, y in self.cells[r]}
        way |= {(x + ddx, y + ddy) for x, y in zip(self.opx[hold].tolist(),
                                                   self.opy[hold].tolist())}
        # and every robot a push along the crowd may reach (kernel.CHAIN_DEPTH)
        wx = np.array([p[0] for p in way], dtype=np.int64)
        wy = np.array([p[1] for p in way], dtype=np.int64)
        px = self.opx[lo:hi]
        py = self.opy[lo:hi]
        d = kernel.CHAIN_DEPTH
        near = np.flatnonzero((px >= wx.min() - d) & (px <= wx.max() + d)
                              & (py >= wy.min() - d) & (py <= wy.max() + d))
        cheb = np.maximum(np.abs(px[near, None] - wx[None, :]),
                          np.abs(py[near, None] - wy[None, :])).min(axis=1)
        mask = self.held[lo:hi] >= 0
        mask[near[cheb <= d]] = True
        sub = (lo + np.flatnonzero(mask)).tolist()
        xs = self.x[sub].tolist()
        ys = self.y[sub].tolist()
        held = [int(k) - base if k >= 0 else -1 for k in self.held[sub].tolist()]
        cx = [c[0] for c in self.cells[r]]
        cy = [c[1] for c in self.cells[r]]
        grid = slice(base, base + self.stride)
        stamp = np.full(self.stride, -1, dtype=np.int64)
        if not kernel.make_way(self.obj[grid], self.occ[grid], stamp, 0, w, nn, xs, ys, 0,
                               len(sub), held, cx, cy, 0, len(cx), ddx, ddy, 1):
            return False
        self.x[sub] = xs
        self.y[sub] = ys
        entered.extend((base + np.flatnonzero(stamp == 1)).tolist())
        return True

    # -- exchange ------------------------------------------------------------------------------

    def _exchange(self, t: int, sends: list) -> None:
        called: set[int] = set()
        if sends:
            gs, orders, kinds, fields = [], [], [], []
            for g, order, kind, f in sends:
                if kind == msg.HEARTBEAT:
                    # a heartbeat changes the coordinator only if the node is not
                    # announced yet or it is the leader during transport
                    r = self.rid[g]
                    keep = ((self.announced[g] == 0)
                            | ((self.node[g] == self.c_leader[r]) & (self.c_step[r] > 0)))
                    if not keep.all():
                        g = g[keep]
                        f = tuple(a[keep] for a in f)
                    if not len(g):
                        continue
                nf = len(msg.fields(kind))
                cols = np.zeros((len(g), 6), dtype=np.int64)
                for j in range(nf):
                    cols[:, j] = f[j]
                gs.append(g)
                orders.append(np.full(len(g), order, dtype=np.int64))
                kinds.append(np.full(len(g), kind, dtype=np.int64))
                fields.append(cols)
            if gs:
                g = np.concatenate(gs)
                o = np.concatenate(orders)
                kd = np.concatenate(kinds)
                fc = np.concatenate(fields)
                srt = np.lexsort((o, g))
                g, kd, fc = g[srt], kd[srt], fc[srt]
                runs = self.rid[g].tolist()
                nodes = self.node[g].tolist()
                gl = g.tolist()
                kl = kd.tolist()
                fl = fc.tolist()
                coords = self.coords
                for i in range(len(gl)):
                    kind = kl[i]
                    r = runs[i]
                    coords[r].on_message(nodes[i], kind, tuple(fl[i][:len(msg.fields(kind))]), t)
                    if kind == msg.HELLO:
                        self.announced[gl[i]] = 1
                    called.add(r)
        for r in np.flatnonzero(self.c_conv & self.alive).tolist():
            called.add(r)
        inbox = self.inbox
        for r in sorted(called):
            c = self.coords[r]
            out = c.tick(t)
            self.c_leader[r] = c.leader
            self.c_step[r] = c.step
            self.c_conv[r] = c.converged_tick >= 0
            if out:
                start = int(self.run_start[r])
                agents = self.runs[r][0].agents
                for node, kind, fields in out:
                    f = tuple(fields)
                    if node == msg.HOST:
                        inbox.extend((start + j, kind, f) for j in range(agents))
                    else:
                        inbox.append((start + node - 1, kind, f))

    # -- run ends ---------------------------------------------------------------------------------

    def _finish(self, t: int) -> None:
        live = np.flatnonzero(self.alive)
        if not len(live):
            return
        done = []
        for r in live.tolist():
            c = self.coords[r]
            stop = (c.done() if self.until == "delivered"
                    else c.converged_tick >= 0 or c.done())
            if stop or t >= self.max_ticks[r]:
                done.append(r)
        if not done:
            return
        for r in done:
            self._result(r, t)
            self.alive[r] = False
            lo = int(self.run_start[r])
            hi = lo + self.runs[r][0].agents
            self.state[lo:hi] = DEAD
            self.hello_acked[lo:hi] = 1
            self.pending[lo:hi] = 0
            self.has_carry[lo:hi] = 0
            self.dead_robots += hi - lo
        self.inbox = [m for m in self.inbox if self.alive[self.rid[m[0]]]]
        if self.dead_robots * 2 >= len(self.node) and self.alive.any():
            self._compact()

    def _result(self, r: int, t: int) -> None:
        sc, seed = self.runs[r]
        traj = []
        if self.record:
            lo_hi = [(int(st[r]), int(st[r]) + sc.agents) for _, _, st in self.frames]
            traj = [(fx_[a:b].tolist(), fy_[a:b].tolist())
                    for (fx_, fy_, _), (a, b) in zip(self.frames, lo_hi)]
        self.results[r] = RunResult(sc, seed, t, _ObjCells(list(self.cells[r])),
                                    self.coords[r], [], traj)

    def _compact(self) -> None:
        keep = np.flatnonzero(self.state != DEAD)
        n_old = len(self.state)
        old_slots = self.run_slot.copy()
        live_runs = np.flatnonzero(self.alive)
        # grids: keep the live runs' slots, in slot order
        slots = old_slots[live_runs]
        order = np.argsort(slots)
        live_runs = live_runs[order]
        slots = slots[order]
        for name in ("obj", "owner", "field", "occ"):
            a = getattr(self, name).reshape(-1, self.stride)[slots].reshape(-1)
            setattr(self, name, a)
        self.run_slot[:] = -1
        self.run_slot[live_runs] = np.arange(len(live_runs))
        shift = (self.run_slot[self.rid[keep]] - old_slots[self.rid[keep]]) * self.stride
        for name in _ROBOT_FIELDS:
            setattr(self, name, getattr(self, name)[keep])
        self.held = np.where(self.held >= 0, self.held + shift, self.held)
        # robot index remap for the inbox and run starts
        remap = np.full(n_old, -1, dtype=np.int64)
        remap[keep] = np.arange(len(keep))
        self.inbox = [(int(remap[g]), k, f) for g, k, f in self.inbox]
        for r in live_runs.tolist():
            self.run_start[r] = remap[self.run_start[r]]
        self.dead_robots = 0
        self._index()
        # claim/move/beacon intents are rebuilt each tick; nothing else holds indices

    def finished(self) -> bool:
        return not self.alive.any()

    def run(self, progress: Callable[[int], None] | None = None) -> list[RunResult]:
        while not self.finished():
            self.step()
            if progress is not None:
                progress(int((~self.alive).sum()))
        return list(self.results)  # type: ignore[arg-type]


def run_batch_results(scenarios: Scenario | Sequence[Scenario], seeds: Iterable[int],
                      **kw) -> list[RunResult]:
    """sim_backend.batch.engine.run_batch_results, stepped by this engine."""
    from sim_backend.batch import engine as batch
    return batch.run_batch_results(scenarios, seeds, engine=VectorEngine, **kw)


def run_batch(scenarios: Scenario | Sequence[Scenario], seeds: Iterable[int], **kw):
    """sim_backend.batch.engine.run_batch, stepped by this engine."""
    from sim_backend.batch import engine as batch
    return batch.run_batch(scenarios, seeds, engine=VectorEngine, **kw)
