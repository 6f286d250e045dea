"""Every robot's body in a batch of runs, as one HAL object over flat arrays.

`BatchBody` implements firmware_logic/hal.py for robot `i` (set before each
step) by calling the world's rules in sim_backend/kernel.py on the kernel's
world state of every run (kernel.Grid, Robots, Run), the same functions the
reference engine's SimBody calls; `tick_all` runs the kernel's tick of every
live run (kernel.sync_tick, go_iteration), which steps the robots' FSMs
through `turn`. The batch engine transforms this file, the kernel and the
behaviour's firmware modules into array functions and compiles them with
numba (sim_backend/batch/transform.py, soa.py); it stays plain Python so it
can be read, and run uncompiled, like the rest.
"""

from firmware_logic import fixedpoint as fx
from sim_backend import kernel

# rows of the per-robot table (int64[ROBOT_ROWS, robots]): the kernel's
# Robots rows (kernel.ROBOT_FIELDS), then the batch's own
ROBOT_NAMES = kernel.ROBOT_FIELDS + ("run", "in_head", "in_tail")
XS = ROBOT_NAMES.index("xs")
YS = ROBOT_NAMES.index("ys")
HELD = ROBOT_NAMES.index("held")
RUN = ROBOT_NAMES.index("run")              # the robot's run
IN_HEAD = ROBOT_NAMES.index("in_head")      # inbox ring: next message to read
IN_TAIL = ROBOT_NAMES.index("in_tail")      # inbox ring: next free slot
ROBOT_ROWS = len(ROBOT_NAMES)

# rows of the per-run table (int64[RUN_ROWS, runs]): kernel.RUN_FIELDS
BASE = kernel.RUN_FIELDS.index("base")
LO = kernel.RUN_FIELDS.index("lo")
HI = kernel.RUN_FIELDS.index("hi")
C0 = kernel.RUN_FIELDS.index("c0")
C1 = kernel.RUN_FIELDS.index("c1")
LIVE = kernel.RUN_FIELDS.index("live")
STEPS = kernel.RUN_FIELDS.index("steps")
RUN_ROWS = len(kernel.RUN_FIELDS)

# the grids (a tuple of GRID_ROWS arrays of runs * stride cells, kernel.GRID_FIELDS)
OBJ = kernel.GRID_FIELDS.index("obj")
OWNER = kernel.GRID_FIELDS.index("owner")
FIELD = kernel.GRID_FIELDS.index("field")
OCC = kernel.GRID_FIELDS.index("occ")
STAMP = kernel.GRID_FIELDS.index("stamp")
GRID_ROWS = len(kernel.GRID_FIELDS)
# Each grid's element type: the smallest that holds its values, because every
# probe of every robot reads the object and occupancy grids at a random cell
# and a 10,000-robot arena's grids then stay near the core (docs/performance.md).
# Object codes are 0..3; a patch holds at most every robot of its run (agents
# <= 20,000, scenario.py); ticks <= 10,000,000, nodes and field sums fit int32.
GRID_TYPES = ("int8", "int32", "int32", "int16", "int32")

FIELDS = 6      # message fields a HAL send() carries


class BatchBody:
    def __init__(self, grid, rb, runs, robots, out_i, out_kind, out_f, out_n,
                 in_kind, in_nf, in_f):
        self.i = 0
        self.g = grid               # the kernel's world state (kernel.Grid, Robots, Run)
        self.rb = rb
        self.runs = runs
        self.run = robots[RUN]
        self.in_head = robots[IN_HEAD]
        self.in_tail = robots[IN_TAIL]
        self.out_i = out_i          # the robot that sent message j of this tick
        self.out_kind = out_kind
        self.out_f = out_f          # [messages, FIELDS]
        self.out_n = out_n          # [count this tick, 1 if a send found the outbox full]
        self.in_kind = in_kind      # [robots, ring size]
        self.in_nf = in_nf          # fields each inbox message carries
        self.in_f = in_f            # [robots, ring size, FIELDS]

    def turn(self, robot, i):
        """Robot i's FSM steps once on this body (the kernel's turn loops ask
        it, and fetch what the turns ahead read: kernel.WARM_MIN)."""
        self.i = i
        robot.step(self)

    def dead(self):
        return kernel.dead(self.rb, self.runs, self.run[self.i], self.i)

    # -- sensing ------------------------------------------------------------------

    def x(self):
        return self.rb.xs[self.i]

    def y(self):
        return self.rb.ys[self.i]

    def probe(self, heading):
        i = self.i
        r = self.run[i]
        p = kernel.probe(self.g, self.runs, r, self.rb.xs[i], self.rb.ys[i], heading)
        return kernel.sensed_probe(self.rb, self.runs, r, i, p)

    def field_ahead(self, heading):
        i = self.i
        r = self.run[i]
        v = kernel.field_ahead(self.g, self.runs, r, self.rb.xs[i], self.rb.ys[i], heading)
        return kernel.sensed_field(self.rb, self.runs, r, i, v)

    def field_here(self):
        i = self.i
        r = self.run[i]
        v = kernel.field_here(self.g, self.runs, r, self.rb.xs[i], self.rb.ys[i])
        return kernel.sensed_field(self.rb, self.runs, r, i, v)

    def uphill(self):
        i = self.i
        r = self.run[i]
        u = kernel.uphill(self.g, self.rb, self.runs, r, i)
        return kernel.sensed_uphill(self.rb, self.runs, r, i, u)

    def holding(self):
        return kernel.holding(self.g, self.rb, self.runs, self.run[self.i], self.i)

    # -- acting: intents ----------------------------------------------------------------

    def forward(self, heading, step):
        i = self.i
        if kernel.stuck(self.rb, self.runs, self.run[i], i) == 1:
            return
        self.rb.mv_on[i] = 1
        self.rb.mv_h[i] = heading
        self.rb.mv_step[i] = step

    def claim(self, heading):
        if self.dead():
            return
        self.rb.claim[self.i] = kernel.claim_cell(self.rb, self.runs, self.run[self.i],
                                                  self.i, heading)

    def carry(self, dx, dy):
        if self.dead():
            return
        self.rb.carry_on[self.i] = 1
        self.rb.carry_dx[self.i] = dx
        self.rb.carry_dy[self.i] = dy

    def beacon(self, on):
        if self.dead():
            return
        self.rb.beacon_set[self.i] = on

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
        r = self.run[i]
        head = self.in_head[i]
        if head == self.in_tail[i]:
            return 0
        slot = head % self.in_kind.shape[1]
        # lost on a dead robot, or a defiant one's TRANSPORT and HALT
        while kernel.drops(self.rb, self.runs, r, i, self.in_kind[i, slot]) == 1:
            head += 1
            self.in_head[i] = head
            if head == self.in_tail[i]:
                return 0
            slot = head % self.in_kind.shape[1]
        for j in range(self.in_nf[i, slot]):
            buf[j] = self.in_f[i, slot, j]
        self.in_head[i] = head + 1
        return self.in_kind[i, slot]


def tick_all(robots, body, tick):
    """One tick of every live run: kernel.sync_tick, or under activation
    netlogo kernel.go_iteration.

    A run smaller than kernel.WARM_MIN fetches nothing ahead of its own
    turns, and in a batch of many such runs every run's patches were last
    read a whole step ago: its turns and moves waited on the patches' cache
    misses (docs/performance.md, "Small runs: the compiled tick at 20
    robots"). So while a run steps, the patches round the robots of the next
    live run are fetched (warm_run), and the positions of the one after it,
    which that fetch reads."""
    body.out_n[0] = 0
    runs = body.runs
    nr = len(runs.live)
    r = next_live(runs, 0)
    a = next_live(runs, r + 1)
    while r < nr:
        b = next_live(runs, a + 1)
        if a < nr and runs.hi[a] - runs.lo[a] < kernel.WARM_MIN:
            warm_run(body, a, b)
        runs.tick[r] = tick
        if runs.act[r] == kernel.SYNC:
            kernel.sync_tick(robots, body, body.g, body.rb, runs, r)
        else:
            kernel.go_iteration(robots, body, body.g, body.rb, runs, r)
        r = a
        a = b


def next_live(runs, r):
    """The first live run from r on, len(runs.live) if none."""
    live = runs.live
    while r < len(live) and live[r] != 1:
        r += 1
    return r


def warm_run(body, a, b):
    """A prefetch of what run a's tick reads at random (kernel.warm_patches
    round each robot, and the stamp rows its moves test), and of run b's
    positions (the next call's reads), one line of each."""
    g = body.g
    rb = body.rb
    runs = body.runs
    n = runs.n[a]
    first = runs.base[a]
    last = first + n * n - 1
    for i in range(runs.lo[a], runs.hi[a]):
        kernel.warm_patches(g, runs, a, rb.xs[i], rb.ys[i])
        c = first + kernel.cell(runs.w[a], n, fx.patch(rb.xs[i]), fx.patch(rb.ys[i]))
        kernel.prefetch(g.stamp, max(first, c - n))
        kernel.prefetch(g.stamp, c)
        kernel.prefetch(g.stamp, min(last, c + n))
    if b < len(runs.live):
        for i in range(runs.lo[b], runs.hi[b], 8):
            kernel.prefetch(rb.xs, i)
            kernel.prefetch(rb.ys, i)
        kernel.prefetch(rb.xs, runs.hi[b] - 1)
        kernel.prefetch(rb.ys, runs.hi[b] - 1)


def states_of(robots, out):
    """Every robot's FSM state, for traces."""
    for i in range(len(robots)):
        out[i] = robots[i].state


def sift(out_i, out_kind, out_f, width, muted, repeats, same, same_n, run, kept, ended, n):
    """The first n messages of the outbox (sender robot, kind, `width`
    fields each) that reach their coordinators, by the rule of
    sim_backend/exchange.py's Muting.drops, in the order sent: into kept's
    rows (message number, sender, kind, fields); returns how many. A
    message of the kind `muted` marks for its sender is dropped; one of the
    kind of its sender's repeat clause (`repeats`) is dropped while its
    first same_n[r] fields are its run r's `same` (same_n -1: none are),
    and otherwise kept, ending the clause: the sender goes into `ended`
    (ended[0] counts them) for the host's declaration to end it too."""
    k = 0
    e = 0
    for j in range(n):
        i = out_i[j]
        kind = out_kind[j]
        if muted[i] == kind:
            continue
        if repeats[i] == kind:
            r = run[i]
            m = same_n[r]
            hit = 1 if m >= 0 else 0
            c = 0
            while hit == 1 and c < m:
                if out_f[j, c] != same[r, c]:
                    hit = 0
                c += 1
            if hit == 1:
                continue
            repeats[i] = -1
            e += 1
            ended[e] = i
        kept[k, 0] = j
        kept[k, 1] = i
        kept[k, 2] = kind
        for c in range(width):
            kept[k, 3 + c] = out_f[j, c]
        k += 1
    ended[0] = e
    return k


def deliver(in_kind, in_nf, in_f, in_head, in_tail, inbox, todo, table, m):
    """Commands into the robots' inbox rings: m spans of todo (first robot,
    robots, row of `table`: kind, field count, FIELDS fields), each robot's
    in the order given. Nothing is written when one would find its robot's
    ring full: returns that robot, else -1."""
    w = 2 + FIELDS
    bad = -1
    j = 0
    while j < m and bad < 0:
        first = todo[3 * j]
        for i in range(first, first + todo[3 * j + 1]):
            if bad < 0 and in_tail[i] - in_head[i] >= inbox:
                bad = i
            in_tail[i] += 1
        j += 1
    for s in range(j):       # the count's own increments, undone
        first = todo[3 * s]
        for i in range(first, first + todo[3 * s + 1]):
            in_tail[i] -= 1
    if bad >= 0:
        return bad
    for s in range(m):
        first = todo[3 * s]
        row = todo[3 * s + 2] * w
        kind = table[row]
        nf = table[row + 1]
        for i in range(first, first + todo[3 * s + 1]):
            slot = in_tail[i] % inbox
            in_kind[i, slot] = kind
            in_nf[i, slot] = nf
            for c in range(FIELDS):
                in_f[i, slot, c] = table[row + 2 + c]
            in_tail[i] += 1
    return -1
