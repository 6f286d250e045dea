"""Every robot's body in a batch of runs, as one HAL object over flat arrays.

`BatchBody` implements firmware_logic/hal.py for robot `i` (set before each
step) by calling the world's rules in sim_backend/kernel.py, the same
functions the reference engine's SimBody calls; `tick_all` steps every live
robot's FSM and applies the intents run by run. The batch engine transforms
this file, the kernel and the behaviour's firmware modules into array
functions and compiles them with numba (sim_backend/batch/transform.py,
soa.py); it stays plain Python so it can be read, and run uncompiled, like
the rest.
"""

from firmware_logic import messages as msg
from sim_backend import faults, kernel

# rows of the per-robot table (int64[ROBOT_ROWS, robots])
XS = 0
YS = 1
HELD = 2
MV_ON = 3
MV_H = 4
MV_STEP = 5
CLAIM = 6
BEACON_SET = 7
BEACON_ON = 8
BSX = 9
BSY = 10
CARRY_ON = 11
CARRY_DX = 12
CARRY_DY = 13
RUN = 14        # the robot's run
IN_HEAD = 15    # inbox ring: next message to read
IN_TAIL = 16    # inbox ring: next free slot
TIE = 17        # uphill's tie-break stream (kernel.tie_seed)
ORDER = 18      # activation netlogo: this go iteration's order (robot indices)
DIE = 19        # faults (sim_backend/faults.py plan): tick it dies
STUCK0 = 20     # first tick stuck in place
STUCK1 = 21     # first tick free again
FLAGS = 22      # faults.IGNORE_FIELD | IGNORE_HOST | RANDOM
ROBOT_ROWS = 23

# rows of the per-run table (int64[RUN_ROWS, runs])
BASE = 0        # first cell of the run's grids
W = 1           # worldSize
N = 2           # 2 * worldSize + 1
LO = 3          # first robot (node 1)
HI = 4          # one past the last robot
T0 = 5          # the run's Signal table entries
T1 = 6
C0 = 7          # the run's object cells
C1 = 8
LIVE = 9        # 1 while the run goes on
SIGMODE = 10    # signalMode (kernel.ON_PATCH, LAST_FINDER)
RADIUS = 11     # sigRadius
TIES = 12       # uphillTies (kernel.ORDERED, AT_RANDOM)
ACT = 13        # activation (kernel.SYNC, SEQUENTIAL)
ORDER_RNG = 14  # activation netlogo: the order stream (kernel.order_seed)
FIELD_STATE = 15  # the behaviour's field state (World.field_state)
EXTRA_STEPS = 16   # world.extra_steps: the MULTI_STEP parameter's value
STEPS = 17      # activation netlogo: FSM steps of the run's robots so far
RULES = 18      # the arena's rules (kernel.DYNAMIC, YIELD flags)
FAULTY = 19     # 1 if the run injects faults (faults.active)
FSEED = 20      # faults.per_run: the draws' seed, probe miss, ghost, field noise
MISS = 21
GHOST = 22
NOISE = 23
RUN_ROWS = 24

# the grids (a tuple of GRID_ROWS arrays of runs * stride cells)
OBJ = 0
OWNER = 1
FIELD = 2
OCC = 3
STAMP = 4
GRID_ROWS = 5
# Each grid's element type: the smallest that holds its values, because every
# probe of every robot reads the object and occupancy grids at a random cell
# and a 10,000-robot arena's grids then stay near the core (docs/performance.md).
# Object codes are 0..3; a patch holds at most every robot of its run (agents
# <= 20,000, scenario.py); ticks <= 10,000,000, nodes and field sums fit int32.
GRID_TYPES = ("int8", "int32", "int32", "int16", "int32")

FIELDS = 6      # message fields a HAL send() carries


class BatchBody:
    def __init__(self, grids, robots, runs, cells, table, out_i, out_kind, out_f, out_n,
                 in_kind, in_nf, in_f):
        self.i = 0
        self.obj = grids[OBJ]
        self.owner = grids[OWNER]
        self.field = grids[FIELD]
        self.occ = grids[OCC]
        self.stamp = grids[STAMP]
        self.xs = robots[XS]
        self.ys = robots[YS]
        self.held = robots[HELD]
        self.mv_on = robots[MV_ON]
        self.mv_h = robots[MV_H]
        self.mv_step = robots[MV_STEP]
        self.claim_k = robots[CLAIM]
        self.beacon_set = robots[BEACON_SET]
        self.beacon_on = robots[BEACON_ON]
        self.bsx = robots[BSX]
        self.bsy = robots[BSY]
        self.carry_on = robots[CARRY_ON]
        self.carry_dx = robots[CARRY_DX]
        self.carry_dy = robots[CARRY_DY]
        self.run = robots[RUN]
        self.in_head = robots[IN_HEAD]
        self.in_tail = robots[IN_TAIL]
        self.tie = robots[TIE]
        self.order = robots[ORDER]
        self.die = robots[DIE]
        self.stuck0 = robots[STUCK0]
        self.stuck1 = robots[STUCK1]
        self.flags = robots[FLAGS]
        self.faulty = runs[FAULTY]
        self.fseed = runs[FSEED]
        self.miss = runs[MISS]
        self.ghost = runs[GHOST]
        self.noise = runs[NOISE]
        self.t = 0                  # the tick being stepped
        self.k = 0                  # fault draws of robot i this tick
        self.base = runs[BASE]
        self.w = runs[W]
        self.n = runs[N]
        self.lo = runs[LO]
        self.hi = runs[HI]
        self.t0 = runs[T0]
        self.t1 = runs[T1]
        self.c0 = runs[C0]
        self.c1 = runs[C1]
        self.live = runs[LIVE]
        self.sigmode = runs[SIGMODE]
        self.radius = runs[RADIUS]
        self.ties = runs[TIES]
        self.act = runs[ACT]
        self.order_rng = runs[ORDER_RNG]
        self.field_state = runs[FIELD_STATE]
        self.extra_steps = runs[EXTRA_STEPS]
        self.steps = runs[STEPS]
        self.rules = runs[RULES]
        self.cx = cells[0]
        self.cy = cells[1]
        self.cv = cells[2]
        self.cw = cells[3]
        self.tdx = table[0]
        self.tdy = table[1]
        self.tv = table[2]
        self.out_i = out_i          # the robot that sent message j of this tick
        self.out_kind = out_kind
        self.out_f = out_f          # [messages, FIELDS]
        self.out_n = out_n          # [count this tick, 1 if a send found the outbox full]
        self.in_kind = in_kind      # [robots, ring size]
        self.in_nf = in_nf          # fields each inbox message carries
        self.in_f = in_f            # [robots, ring size, FIELDS]

    # -- faults (sim_backend/faults.py; the reference's are in sim_backend/body.py) --

    def dead(self):
        return self.faulty[self.run[self.i]] == 1 and self.t >= self.die[self.i]

    def _draw(self):
        self.k += 1
        return faults.draw(self.fseed[self.run[self.i]], self.i - self.lo[self.run[self.i]],
                           self.t, self.k)

    def _sensed_field(self, v):
        if self.flags[self.i] & (faults.IGNORE_FIELD | faults.RANDOM):
            return 0
        nz = self.noise[self.run[self.i]]
        if nz:
            v += self._draw() % (2 * nz + 1) - nz
        return v if v > 0 else 0

    # -- sensing ------------------------------------------------------------------

    def x(self):
        return self.xs[self.i]

    def y(self):
        return self.ys[self.i]

    def probe(self, heading):
        r = self.run[self.i]
        p = kernel.probe(self.obj, self.occ, self.base[r], self.w[r], self.n[r],
                         self.xs[self.i], self.ys[self.i], heading, self.rules[r])
        if self.faulty[r] == 1:
            if p == kernel.OBJECT and self.flags[self.i] & faults.RANDOM:
                p = kernel.ROBOT
            elif p == kernel.OBJECT and self.miss[r] and self._draw() < self.miss[r]:
                p = kernel.NOTHING
            elif p == kernel.NOTHING and self.ghost[r] and self._draw() < self.ghost[r]:
                p = kernel.OBJECT
        return p

    def field_ahead(self, heading):
        r = self.run[self.i]
        v = kernel.field_ahead(self.field, self.base[r], self.w[r], self.n[r],
                               self.xs[self.i], self.ys[self.i], heading, self.rules[r])
        if self.faulty[r] == 1:
            v = self._sensed_field(v)
        return v

    def field_here(self):
        r = self.run[self.i]
        v = kernel.field_here(self.field, self.base[r], self.w[r], self.n[r],
                              self.xs[self.i], self.ys[self.i])
        if self.faulty[r] == 1:
            v = self._sensed_field(v)
        return v

    def uphill(self):
        r = self.run[self.i]
        u = kernel.uphill(self.field, self.base[r], self.w[r], self.n[r],
                          self.xs[self.i], self.ys[self.i], self.ties[r], self.tie, self.i,
                          self.rules[r])
        if self.faulty[r] == 1 and self.flags[self.i] & (faults.IGNORE_FIELD | faults.RANDOM):
            return -1
        return u

    def holding(self):
        r = self.run[self.i]
        return kernel.holding(self.owner, self.base[r], self.held[self.i],
                              self.i - self.lo[r] + 1)

    # -- acting: intents ----------------------------------------------------------------

    def forward(self, heading, step):
        if self.dead() or (self.faulty[self.run[self.i]] == 1
                           and self.stuck0[self.i] <= self.t < self.stuck1[self.i]):
            return
        self.mv_on[self.i] = 1
        self.mv_h[self.i] = heading
        self.mv_step[self.i] = step

    def claim(self, heading):
        if self.dead():
            return
        r = self.run[self.i]
        self.claim_k[self.i] = kernel.ahead_cell(self.w[r], self.n[r], self.xs[self.i],
                                                 self.ys[self.i], heading, self.rules[r])

    def carry(self, dx, dy):
        if self.dead():
            return
        self.carry_on[self.i] = 1
        self.carry_dx[self.i] = dx
        self.carry_dy[self.i] = dy

    def beacon(self, on):
        if self.dead():
            return
        self.beacon_set[self.i] = on

    # -- messages ------------------------------------------------------------------------

    def send(self, kind, a0, a1, a2, a3, a4, a5):
        if self.dead():
            return
        j = self.out_n[0]
        if j >= len(self.out_kind):
            self.out_n[1] = 1               # the engine stops with a named error
            return
        self.out_i[j] = self.i
        self.out_kind[j] = kind
        self.out_f[j, 0] = a0
        self.out_f[j, 1] = a1
        self.out_f[j, 2] = a2
        self.out_f[j, 3] = a3
        self.out_f[j, 4] = a4
        self.out_f[j, 5] = a5
        self.out_n[0] = j + 1

    def recv(self, buf):
        i = self.i
        head = self.in_head[i]
        if head == self.in_tail[i]:
            return 0
        slot = head % self.in_kind.shape[1]
        if self.faulty[self.run[i]] == 1:
            # lost on a dead robot, or a defiant one's TRANSPORT and HALT
            while self.dead() or (self.flags[i] & faults.IGNORE_HOST and (
                    self.in_kind[i, slot] == msg.TRANSPORT
                    or self.in_kind[i, slot] == msg.HALT)):
                head += 1
                self.in_head[i] = head
                if head == self.in_tail[i]:
                    return 0
                slot = head % self.in_kind.shape[1]
        for j in range(self.in_nf[i, slot]):
            buf[j] = self.in_f[i, slot, j]
        self.in_head[i] = head + 1
        return self.in_kind[i, slot]

    # -- the world's tick ------------------------------------------------------------------

    def apply(self, r, tick):
        kernel.apply_tick(self.obj, self.owner, self.field, self.occ, self.stamp,
                          self.base[r], self.w[r], self.n[r], self.tdx, self.tdy, self.tv,
                          self.t0[r], self.t1[r], self.xs, self.ys, self.lo[r], self.hi[r],
                          self.held, self.mv_on, self.mv_h, self.mv_step, self.claim_k,
                          self.beacon_set, self.beacon_on, self.bsx, self.bsy, self.carry_on,
                          self.carry_dx, self.carry_dy, self.cx, self.cy, self.cv, self.cw,
                          self.c0[r], self.c1[r], tick, self.sigmode[r], self.radius[r],
                          self.rules[r])


    def end_iteration(self, r, tick):
        kernel.end_iteration(self.obj, self.owner, self.field, self.occ, self.stamp,
                             self.base[r], self.w[r], self.n[r], self.tdx, self.tdy, self.tv,
                             self.t0[r], self.t1[r], self.xs, self.ys, self.lo[r], self.hi[r],
                             self.held, self.beacon_set, self.beacon_on, self.bsx, self.bsy,
                             self.carry_on, self.carry_dx, self.carry_dy, self.cx, self.cy,
                             self.cv, self.cw, self.c0[r], self.c1[r], tick, self.sigmode[r],
                             self.radius[r], self.order, self.rules[r])


def tick_all(robots, body, tick):
    """One tick of every live run. Synchronous runs: each robot steps against
    the tick-start world in node order, then each run's intents are applied.
    Sequential runs (activation netlogo): one go iteration, go_iteration."""
    body.out_n[0] = 0
    body.t = tick
    for i in range(len(robots)):
        r = body.run[i]
        if body.live[r] == 1 and body.act[r] == kernel.SYNC:
            body.i = i
            body.k = 0
            body.mv_on[i] = 0
            body.claim_k[i] = -1
            body.beacon_set[i] = -1
            if body.faulty[body.run[i]] == 1 and tick == body.die[i]:
                # it goes limp: beacon off, grip released (faults.release)
                body.beacon_set[i] = 0
                faults.release(body.obj, body.owner, body.base[body.run[i]], body.held, i)
            robots[i].step(body)
    for r in range(len(body.live)):
        if body.live[r] == 1:
            if body.act[r] == kernel.SYNC:
                body.apply(r, tick)
            else:
                go_iteration(robots, body, r, tick)


def go_iteration(robots, body, r, tick):
    """NetLogo's `ask robots` for run r, as Engine._go_iteration: each robot in
    a freshly drawn order takes its turn's steps, each applied at once; then
    the iteration's beacons and the carried group."""
    lo = body.lo[r]
    hi = body.hi[r]
    fs = body.field_state[r]
    fd = body.extra_steps[r]
    for i in range(lo, hi):
        body.beacon_set[i] = -1
    kernel.draw_order(body.order, lo, hi, body.order_rng, r)
    for j in range(lo, hi):
        i = body.order[j]
        body.i = i
        steps = kernel.turn_steps(robots[i].state, fs, fd)
        k = 0
        while k < steps:
            was = robots[i].state
            body.mv_on[i] = 0
            body.claim_k[i] = -1
            robots[i].step(body)
            claimed = body.claim_k[i] >= 0
            kernel.apply_robot(body.obj, body.owner, body.occ, body.base[r], body.w[r],
                               body.n[r], body.xs, body.ys, lo, i, body.held, body.mv_on,
                               body.mv_h, body.mv_step, body.claim_k, body.rules[r])
            body.steps[r] += 1
            steps = kernel.turn_length(steps, k, claimed, was, robots[i].state, fs, fd)
            k += 1
    body.end_iteration(r, tick)


def states_of(robots, out):
    """Every robot's FSM state, for traces."""
    for i in range(len(robots)):
        out[i] = robots[i].state
