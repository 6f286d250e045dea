"""The world's rules, written once: sensing, claims, beacons, the carried
group, moves and occupancy, faults, and the turn loops of both activations
(docs/tick-semantics.md).

Every function works on one world state, three bundles of flat integer
arrays: Python lists when the reference engine (sim_backend/engine.py)
interprets them for one run, numpy arrays when the batch engine
(sim_backend/batch/) compiles this very source with numba for many runs at
once. So the code keeps to what both understand: ints, indexing, loops,
attributes of the bundles, calls to the functions here and in
firmware_logic/fixedpoint.py; no sets, dicts, tuples of tuples or
allocation.

The world state:
    g (Grid): the grids (GRID_FIELDS: obj, owner, field, occ, stamp); run r's
        n x n patches start at run.base[r]; a patch (px, py) is cell
        (py + w) * n + (px + w), where w is the run's worldSize and
        n = 2w + 1; `held`, `claim` and the object cells hold cells relative
        to the base; the Signal tables (tdx, tdy, tv: run r's entries
        run.t0[r] to run.t1[r]); the carried objects' cells (cx, cy from
        run.c0[r] to run.c1[r]; cv, cw are scratch);
    rb (Robots): one row per ROBOT_FIELDS name, robot i at index i; run r's
        robots are run.lo[r]..run.hi[r]-1, in node order, so robot i is node
        i - lo + 1;
    run (Run): one row per RUN_FIELDS name, run r at index r (the reference
        engine's World has one run, r = 0): its bounds, modes, streams and
        the tick being stepped.
"""

from firmware_logic import fixedpoint as fx
from firmware_logic import messages as msg
from firmware_logic.hal import BEACON_LEADER, CLAIMED, NOTHING, OBJECT, ROBOT, WALL
from sim_backend import faults

FREE = 0
YELLOW = 1   # a free object segment
BLUE = 2     # a segment a robot holds
OBSTACLE = 3  # a patch of an obstacle: robots probe it as a wall

# beacon_on flags: the robot's field is in the grid (and goes when it turns
# off); the robot pins its own patch's field to LEADER_FIELD every tick
EMITS = 1
PINS = 2
LEADER_FIELD = 10   # Appendix A, go: `set field 10` for a leader

# per-run modes (Scenario.CHOICES order: 0 is the project's default)
ORDERED = 0         # uphillTies: first in N, NE, E, ... order
AT_RANDOM = 1       # uphillTies: NetLogo's random winner
ON_PATCH = 0        # signalMode: every holder, centred on its patch
LAST_FINDER = 1     # signalMode: the tick's last finder, on its position
# the arena's rules (a run's `rules`, flags; 0: the thesis's)
DYNAMIC = 1         # field "dynamic": a beacon's field moves with its holder
                    # (thesis 6.1.3); without, it stays where it was lit
YIELD = 2           # crowd "yield": robots in the carried object's way step
                    # aside; without, any robot there blocks the step
WRAP = 4            # wrap: the search phase is toroidal as NetLogo's default
                    # world (moves, probes, uphill and the field wrap at the
                    # edges); the carried object stays inside the arena
SELF_COUNTS = 8     # probeSelf "netlogo": a probe whose point one ahead falls in
                    # the robot's own patch sees the robot itself (HeadCarefully's
                    # `any? turtles-on patch-at-heading-and-distance heading 1`
                    # counts the caller); without, the robot is not counted
TOWARDS = 16        # uphillHeading "netlogo": uphill's heading points from the
                    # robot's position to the winning patch's centre (NetLogo 3's
                    # reporter, which depends on where the robot stands in its
                    # patch); without, a multiple of 45 degrees

# crowd "yield": how many patches a push along a crowd may reach (make_way)
CHAIN_DEPTH = 4

# the per-robot tie-break stream of uphill (a 31-bit LCG, so numba's int64
# and Python's ints agree without overflow)
TIE_MUL = 1103515245
TIE_ADD = 12345
TIE_MOD = 2147483648

# the neighbours `uphill` looks at, in the order it breaks ties
UPHILL_H = (0, 45, 90, 135, 180, 225, 270, 315)
UPHILL_DX = (0, 1, 1, 1, 0, -1, -1, -1)
UPHILL_DY = (1, 1, 0, -1, -1, -1, 0, 1)

# a run of WARM_MIN robots or more: under activation netlogo the robot
# WARM_ROW turns on (its rows, the HAL's rows of it) and the patches round
# and the objects of the one WARM_CELL turns on are fetched ahead
# (prefetch), so their cache lines are in when their turns come; under sync
# the patches round robot i + WARM_ROW (docs/performance.md, "The netlogo
# activation's tick", "Compiled tick at scale")
WARM_MIN = 512
WARM_ROW = 4
WARM_CELL = 2
# activation sync: apply_tick's moves fetch the cells the robot WARM_MOVE
# on enters (its loop does little per robot, so it runs further ahead)
WARM_MOVE = 8

# activation (a run's `act`)
SYNC = 0            # every robot decides on the tick-start world
SEQUENTIAL = 1      # NetLogo's ask, one robot after another


# -- the world state -----------------------------------------------------------------

GRID_FIELDS = ("obj", "owner", "field", "occ", "stamp")
TABLE_FIELDS = ("tdx", "tdy", "tv")
CELL_FIELDS = ("cx", "cy", "cv", "cw")
ROBOT_FIELDS = (
    "xs", "ys",                          # Q8 position
    "held",                              # held cell, -1: none
    "mv_on", "mv_h", "mv_step",          # a forward() this tick, of mv_step along mv_h
    "claim",                             # cell claimed this tick, -1: none
    "beacon_set",                        # -1: no beacon() call this tick
    "beacon_on", "bsx", "bsy",           # field source on (EMITS, PINS), centred on (bsx, bsy)
    "carry_on", "carry_dx", "carry_dy",  # a carry() asked and not yet consumed
    "tie",                               # uphill's tie-break stream (tie_seed)
    "order",                             # activation netlogo: this iteration's order
    "die", "stuck0", "stuck1", "flags",  # faults (sim_backend/faults.py plan)
    "draws",                             # fault draws of the robot this tick
    "near",                              # make_way's robots near the way (_near)
)
RUN_FIELDS = (
    "base", "w", "n",                    # the run's grids: first cell, worldSize, 2w + 1
    "lo", "hi",                          # its robots
    "t0", "t1",                          # its Signal table entries
    "c0", "c1",                          # its carried object's cells
    "live",                              # 1 while the run goes on
    "sigmode", "radius", "ties",         # signalMode, sigRadius, uphillTies
    "act",                               # activation (SYNC, SEQUENTIAL)
    "order_rng",                         # activation netlogo: the order stream (order_seed)
    "field_state", "extra_steps",        # the behaviour's MULTI_STEP state and its extra steps
    "steps",                             # activation netlogo: FSM steps of its robots so far
    "rules",                             # the arena's rules (DYNAMIC, YIELD, ... flags)
    "faulty", "fseed", "miss", "ghost", "noise",   # faults.active, faults.per_run
    "tick",                              # the tick being stepped
    "cdx", "cdy",                        # the carried group's step being tried
)


class Grid:
    """The cells of every run: GRID_FIELDS, TABLE_FIELDS and CELL_FIELDS,
    each one array (or list)."""

    def __init__(self, grids, table, cells):
        for name, a in zip(GRID_FIELDS + TABLE_FIELDS + CELL_FIELDS,
                           list(grids) + list(table) + list(cells)):
            setattr(self, name, a)


class Robots:
    """Every robot's row of each ROBOT_FIELDS name (rows beyond them are the
    engine's own)."""

    def __init__(self, rows):
        for name, a in zip(ROBOT_FIELDS, rows):
            setattr(self, name, a)


class Run:
    """Every run's value of each RUN_FIELDS name, one row per name."""

    def __init__(self, rows):
        for name, a in zip(RUN_FIELDS, rows):
            setattr(self, name, a)


# -- geometry ---------------------------------------------------------------------------

def inside(w, px, py):
    return -w <= px and px <= w and -w <= py and py <= w


def cell(w, n, px, py):
    return (py + w) * n + (px + w)


def fold(w, n, p, rules):
    """Patch coordinate p on the torus when the run wraps (rules WRAP), else p:
    one patch past +w is -w, as in NetLogo's wrapping world."""
    if (rules & WRAP) != 0:
        return (p + w) % n - w
    return p


def fold_q8(w, n, q, rules):
    """A Q8 coordinate q brought back onto the torus (rules WRAP), so that
    fx.patch(q) lies in -w..w; else q itself."""
    if (rules & WRAP) != 0:
        edge = w * fx.ONE + fx.HALF          # the arena's west (south) edge, in Q8
        return (q + edge) % (n * fx.ONE) - edge
    return q


def prefetch(a, k):
    """A hint that a[k] is read soon (robot k's fields when a is the list of
    robots; row k of each per-robot table it holds when a is an object, as
    the HAL): nothing here; the batch engine compiles it to cache prefetches
    (sim_backend/batch/borrow.py, transform.py), which unlike a read never
    wait for their lines."""


def clear(a, lo, hi):
    """a[lo:hi] = 0. The batch engine compiles it to one memset
    (sim_backend/batch/borrow.py): numba compiles this loop's stores with a
    negative-index fix-up each, which keeps LLVM from vectorising it, and
    recount's clearing of a run's occupancy grid was 4-9 % of a tick
    (docs/performance.md)."""
    for k in range(lo, hi):
        a[k] = 0


def prefetch_held(objs, k):
    """A hint that the objects objs[k]'s fields hold (a robot's random
    stream) are read soon; as prefetch. Its row must be in by then: the
    fetch reads it to find them."""


# fx.dx and fx.dy of one patch (fx.ONE) along each whole-degree heading: a
# probe's step is one lookup, not a product and a shift, and the two share
# one heading reduction (the batch engine's compiler merges them)
AHEAD_DX = tuple(fx.dx(h, fx.ONE) for h in range(360))
AHEAD_DY = tuple(fx.dy(h, fx.ONE) for h in range(360))


def degrees(h):
    """h % 360: a compare for a heading already in 0..359 (every heading the
    behaviour keeps), where the compiled modulo is a multiply, shifts and a
    sign fix."""
    if h >= 0 and h < 360:
        return h
    return h % 360


def step_dx(h, step):
    """fx.dx(h, step), by table for a whole patch."""
    if step == fx.ONE:
        return AHEAD_DX[degrees(h)]
    return fx.dx(h, step)


def step_dy(h, step):
    if step == fx.ONE:
        return AHEAD_DY[degrees(h)]
    return fx.dy(h, step)


def ahead_x(x, h):
    """Patch column one patch ahead of Q8 x along heading h."""
    return fx.patch(x + AHEAD_DX[degrees(h)])


def ahead_y(y, h):
    return fx.patch(y + AHEAD_DY[degrees(h)])


def ahead_cell(w, n, x, y, h, rules):
    """Cell (relative) of the patch one ahead along h, wrapped when the run
    wraps: the patch a probe saw, which a claim takes."""
    return cell(w, n, fold(w, n, ahead_x(x, h), rules), fold(w, n, ahead_y(y, h), rules))


def claim_cell(rb, run, r, i, h):
    """The cell robot i claims along heading h (ahead_cell of its position)."""
    return ahead_cell(run.w[r], run.n[r], rb.xs[i], rb.ys[i], h, run.rules[r])


# -- sensing: the world as it stood at the start of the tick ------------------

def probe(g, run, r, x, y, h):
    w = run.w[r]
    n = run.n[r]
    rules = run.rules[r]
    px = fold(w, n, ahead_x(x, h), rules)
    py = fold(w, n, ahead_y(y, h), rules)
    if not inside(w, px, py):
        return WALL
    k = run.base[r] + cell(w, n, px, py)
    o = g.obj[k]
    if o == OBSTACLE:
        return WALL
    if o == YELLOW:
        return OBJECT
    if o == BLUE:
        return CLAIMED
    c = g.occ[k]
    if px == fx.patch(x) and py == fx.patch(y) and (rules & SELF_COUNTS) == 0:
        c -= 1               # the robot itself (a turn within its own patch)
    if c > 0:
        return ROBOT
    return NOTHING


def field_ahead(g, run, r, x, y, h):
    w = run.w[r]
    n = run.n[r]
    rules = run.rules[r]
    px = fold(w, n, ahead_x(x, h), rules)
    py = fold(w, n, ahead_y(y, h), rules)
    if not inside(w, px, py):
        return 0
    return g.field[run.base[r] + cell(w, n, px, py)]


def field_here(g, run, r, x, y):
    return g.field[run.base[r] + cell(run.w[r], run.n[r], fx.patch(x), fx.patch(y))]


def tie_seed(seed, node):
    """Start of robot `node`'s uphill tie stream in run `seed`."""
    return (seed * 7919 + node * 104729 + 1) % TIE_MOD


def uphill(g, rb, run, r, i):
    """Heading from robot i to the strongest neighbour if stronger than
    here, else -1.

    Ties (run.ties ORDERED) go to the first in N, NE, E, ... order; with
    AT_RANDOM one of the tied neighbours is drawn from robot i's stream
    rb.tie[i], as NetLogo's uphill draws `random.nextInt(winners.size)` among
    the neighbours of the greatest value (prim/etc HillCommand, NetLogo
    sources), moving only if that value is greater than here."""
    w = run.w[r]
    n = run.n[r]
    base = run.base[r]
    rules = run.rules[r]
    field = g.field
    x = rb.xs[i]
    y = rb.ys[i]
    px = fx.patch(x)
    py = fx.patch(y)
    here = field[base + cell(w, n, px, py)]
    best = here
    out = -1
    count = 0
    for j in range(8):
        qx = fold(w, n, px + UPHILL_DX[j], rules)
        qy = fold(w, n, py + UPHILL_DY[j], rules)
        if inside(w, qx, qy):
            v = field[base + cell(w, n, qx, qy)]
            if v > best:
                best = v
                out = UPHILL_H[j]
                count = 1
            elif v == best and count > 0:
                count += 1
    if out < 0:
        return out
    if run.ties[r] == ORDERED:
        return aim(x, y, px, py, out // 45, rules)
    tie = rb.tie
    tie[i] = (tie[i] * TIE_MUL + TIE_ADD) % TIE_MOD
    k = (tie[i] >> 16) % count
    for j in range(8):
        qx = fold(w, n, px + UPHILL_DX[j], rules)
        qy = fold(w, n, py + UPHILL_DY[j], rules)
        if inside(w, qx, qy) and field[base + cell(w, n, qx, qy)] == best:
            if k == 0:
                return aim(x, y, px, py, j, rules)
            k -= 1
    return out


def aim(x, y, px, py, j, rules):
    """uphill's heading to neighbour j of patch (px, py): UPHILL_H[j], or with
    TOWARDS the whole degree nearest `towards` that neighbour's centre from
    the Q8 position (x, y) (always within 45 degrees of UPHILL_H[j]; the
    first of equally near headings); integer maths, so the engines agree."""
    h0 = UPHILL_H[j]
    if (rules & TOWARDS) == 0:
        return h0
    ddx = (px + UPHILL_DX[j]) * fx.ONE - x
    ddy = (py + UPHILL_DY[j]) * fx.ONE - y
    best_h = h0
    best = ddx * fx.sin14(h0) + ddy * fx.cos14(h0)
    for d in range(-45, 46):
        h = (h0 + d + 360) % 360
        v = ddx * fx.sin14(h) + ddy * fx.cos14(h)
        if v > best:
            best = v
            best_h = h
    return best_h


def holding(g, rb, run, r, i):
    held = rb.held[i]
    if held >= 0 and g.owner[run.base[r] + held] == i - run.lo[r] + 1:
        return 1
    return 0


# -- faults (sim_backend/faults.py plans them; these are their rules) ---------------

def start_turn(g, rb, run, r, i):
    """Robot i's turn of a synchronous tick begins: no intents and no fault
    draws yet; in a faulty run, a robot whose death tick it is goes limp: its
    beacon dies and its grip lets go (release)."""
    rb.mv_on[i] = 0
    rb.claim[i] = -1
    rb.beacon_set[i] = -1
    if run.faulty[r] == 1:                  # only a faulty run draws (fault_draw)
        rb.draws[i] = 0
        if run.tick[r] == rb.die[i]:
            rb.beacon_set[i] = 0
            release(g, rb, run, r, i)


def release(g, rb, run, r, i):
    """Robot i dies: the segment it held is free again (a limp gripper holds
    nothing up), so the others can claim it and carry without it."""
    k = rb.held[i]
    if k >= 0:
        k += run.base[r]
        if g.owner[k] > 0:
            g.obj[k] = YELLOW
            g.owner[k] = 0
        rb.held[i] = -1


def dead(rb, run, r, i):
    """1 if robot i is dead: its actions, messages and beacon go nowhere."""
    if run.faulty[r] == 1 and run.tick[r] >= rb.die[i]:
        return 1
    return 0


def stuck(rb, run, r, i):
    """1 if robot i cannot move: dead, or in its deadlock."""
    if dead(rb, run, r, i) == 1:
        return 1
    if run.faulty[r] == 1 and rb.stuck0[i] <= run.tick[r] and run.tick[r] < rb.stuck1[i]:
        return 1
    return 0


def fault_draw(rb, run, r, i):
    """Robot i's next fault draw of this tick (faults.draw)."""
    rb.draws[i] += 1
    return faults.draw(run.fseed[r], i - run.lo[r], run.tick[r], rb.draws[i])


def sensed_probe(rb, run, r, i, p):
    """What robot i's probe reports of p: a random agent sees a segment as a
    robot, a probe may miss a segment or see one where none is."""
    if run.faulty[r] == 1:
        if p == OBJECT and (rb.flags[i] & faults.RANDOM) != 0:
            return ROBOT
        if p == OBJECT and run.miss[r] != 0 and fault_draw(rb, run, r, i) < run.miss[r]:
            return NOTHING
        if p == NOTHING and run.ghost[r] != 0 and fault_draw(rb, run, r, i) < run.ghost[r]:
            return OBJECT
    return p


def sensed_field(rb, run, r, i, v):
    """The field value v as robot i senses it: none when it ignores the field
    (or is a random agent), else with the run's noise, never below 0."""
    if run.faulty[r] == 0:
        return v
    if (rb.flags[i] & (faults.IGNORE_FIELD | faults.RANDOM)) != 0:
        return 0
    nz = run.noise[r]
    if nz != 0:
        v += fault_draw(rb, run, r, i) % (2 * nz + 1) - nz
    if v > 0:
        return v
    return 0


def sensed_uphill(rb, run, r, i, u):
    """uphill's heading u as robot i senses it: -1 when it ignores the field."""
    if run.faulty[r] == 1 and (rb.flags[i] & (faults.IGNORE_FIELD | faults.RANDOM)) != 0:
        return -1
    return u


def drops(rb, run, r, i, kind):
    """1 if a message of `kind` to robot i is lost: on a dead robot, or a
    TRANSPORT or HALT on one that ignores the host."""
    if run.faulty[r] == 0:
        return 0
    if dead(rb, run, r, i) == 1:
        return 1
    if (rb.flags[i] & faults.IGNORE_HOST) != 0 and (kind == msg.TRANSPORT or kind == msg.HALT):
        return 1
    return 0


# -- the field --------------------------------------------------------------------

def signal(g, run, r, px, py, sign):
    """Add (sign 1) or remove (sign -1) one beacon's field centred on a patch
    (on the torus when the run wraps: sigRadius <= worldSize, so no patch is
    reached twice)."""
    w = run.w[r]
    n = run.n[r]
    base = run.base[r]
    rules = run.rules[r]
    field = g.field
    tdx = g.tdx
    tdy = g.tdy
    tv = g.tv
    for t in range(run.t0[r], run.t1[r]):
        x = fold(w, n, px + tdx[t], rules)
        y = fold(w, n, py + tdy[t], rules)
        if inside(w, x, y):
            field[base + cell(w, n, x, y)] += sign * tv[t]


def signal_value(d2):
    """Signal (thesis eq. 3): round(10 / (1 + d)) for d = sqrt(d2) / fx.ONE,
    halves rounded up as NetLogo does, in integers: the value is the number
    of k in 0..9 with 10 / (1 + d) >= k + 1/2, that is d <= (19 - 2k) / (2k + 1),
    so no float rounding can differ between the engines."""
    v = 0
    for k in range(10):
        a = 19 - 2 * k
        b = 2 * k + 1
        if d2 * b * b <= a * a * fx.ONE * fx.ONE:
            v += 1
    return v


def signal_at(g, run, r, x, y, sign):
    """Signal as Appendix A writes it, centred on the Q8 position (x, y):
    every patch within the run's radius of the patch holding it (`patches
    in-radius`, by patch centres) gets round(10 / (1 + d)), d its centre's
    distance from the position itself (`distancexy tempx tempy`); NetLogo
    rounds halves up."""
    w = run.w[r]
    n = run.n[r]
    base = run.base[r]
    rules = run.rules[r]
    radius = run.radius[r]
    field = g.field
    px = fx.patch(x)
    py = fx.patch(y)
    for ddy in range(-radius, radius + 1):
        for ddx in range(-radius, radius + 1):
            if ddx * ddx + ddy * ddy > radius * radius:
                continue
            qx = px + ddx
            qy = py + ddy
            ex = qx * fx.ONE - x
            ey = qy * fx.ONE - y
            qx = fold(w, n, qx, rules)   # the distance is the torus's: to the nearest image
            qy = fold(w, n, qy, rules)
            if not inside(w, qx, qy):
                continue
            field[base + cell(w, n, qx, qy)] += sign * signal_value(ex * ex + ey * ey)


def beacons(g, rb, run, r):
    """Beacons turned on or off this tick, then every leader's pinned patch.

    BEACON_ON lights a beacon, BEACON_LEADER a leader's (it pins its patch to
    LEADER_FIELD every tick, Appendix A go's `set field 10`). ON_PATCH: each
    beacon turned on adds the Signal table centred on its robot's patch.
    LAST_FINDER: only the highest node turning on this tick signals (go
    calls Signal once, for the global `found`'s last setter), centred on its
    Q8 position. A beacon turned off takes its field with it (our addition).
    Pins come before the new fields, as go's ask precedes its Signal."""
    last = -1
    if run.sigmode[r] == LAST_FINDER:       # ON_PATCH never reads it
        for i in range(run.lo[r], run.hi[r]):
            if rb.beacon_set[i] >= 1 and rb.beacon_on[i] == 0:
                last = i
    beacons_last(g, rb, run, r, last)


def beacons_last(g, rb, run, r, last):
    """`beacons` with the last finder given (robot index, -1: none)."""
    lo = run.lo[r]
    hi = run.hi[r]
    sigmode = run.sigmode[r]
    beacon_set = rb.beacon_set
    beacon_on = rb.beacon_on
    bsx = rb.bsx
    bsy = rb.bsy
    for i in range(lo, hi):
        b = beacon_set[i]
        if b == 0 and beacon_on[i] != 0:
            if beacon_on[i] & EMITS:
                # our addition: a beacon switched off takes its field with it
                if sigmode == ON_PATCH:
                    signal(g, run, r, bsx[i], bsy[i], -1)
                else:
                    signal_at(g, run, r, bsx[i], bsy[i], -1)
            beacon_on[i] = 0
    for i in range(lo, hi):
        if (beacon_on[i] & PINS) or (beacon_set[i] == BEACON_LEADER and beacon_on[i] == 0):
            g.field[run.base[r] + cell(run.w[r], run.n[r], fx.patch(rb.xs[i]),
                                       fx.patch(rb.ys[i]))] = LEADER_FIELD
    for i in range(lo, hi):
        b = beacon_set[i]
        if b < 1 or beacon_on[i] != 0:
            continue
        pins = PINS if b == BEACON_LEADER else 0
        if sigmode == ON_PATCH:
            bsx[i] = fx.patch(rb.xs[i])
            bsy[i] = fx.patch(rb.ys[i])
            beacon_on[i] = EMITS | pins
            signal(g, run, r, bsx[i], bsy[i], 1)
        elif i == last:
            bsx[i] = rb.xs[i]
            bsy[i] = rb.ys[i]
            beacon_on[i] = EMITS | pins
            signal_at(g, run, r, bsx[i], bsy[i], 1)
        else:
            beacon_on[i] = pins


def recount(g, rb, run, r):
    w = run.w[r]
    n = run.n[r]
    base = run.base[r]
    occ = g.occ
    xs = rb.xs
    ys = rb.ys
    clear(occ, base, base + n * n)
    for i in range(run.lo[r], run.hi[r]):
        occ[base + cell(w, n, fx.patch(xs[i]), fx.patch(ys[i]))] += 1


# -- applying one tick's intents ---------------------------------------------------

def apply_tick(g, rb, run, r):
    """Apply every robot's intents of tick run.tick[r] (>= 1) in the fixed
    order: claims (lowest node wins a segment), beacons, the carried group,
    moves in node order; then recount occupancy. `stamp` marks the patches
    entered this tick with the tick number. The carried object is the one
    whose cells are cx, cy (c0..c1); other objects and obstacles stay put.
    rules: DYNAMIC, the carriers' beacons move with them; YIELD, robots in
    the carried object's way step aside."""
    lo = run.lo[r]
    hi = run.hi[r]
    w = run.w[r]
    n = run.n[r]
    base = run.base[r]
    rules = run.rules[r]
    tick = run.tick[r]
    obj = g.obj
    occ = g.occ
    stamp = g.stamp
    xs = rb.xs
    ys = rb.ys
    held = rb.held
    for i in range(lo, hi):
        k = rb.claim[i]
        if k >= 0 and obj[base + k] == YELLOW:
            obj[base + k] = BLUE
            g.owner[base + k] = i - lo + 1
            held[i] = k
    beacons(g, rb, run, r)
    if carry_group(g, rb, run, r) and (rules & DYNAMIC) != 0:
        carry_beacons(g, rb, run, r)
    # a big run's moves enter patches anywhere in its grids: the cells robot
    # i + WARM_MOVE enters are fetched ahead (WARM_MIN), as the turns' are
    far = hi - WARM_MOVE
    if hi - lo < WARM_MIN:
        far = lo
    for i in range(lo, hi):
        if i < far:
            warm_move(g, rb, run, r, i + WARM_MOVE)
        if rb.mv_on[i] == 0:
            continue
        if held[i] >= 0:
            let_go(g, rb, run, r, i)
        nx = fold_q8(w, n, xs[i] + step_dx(rb.mv_h[i], rb.mv_step[i]), rules)
        ny = fold_q8(w, n, ys[i] + step_dy(rb.mv_h[i], rb.mv_step[i]), rules)
        px = fx.patch(nx)
        py = fx.patch(ny)
        if px != fx.patch(xs[i]) or py != fx.patch(ys[i]):
            if not inside(w, px, py):
                continue
            k = base + cell(w, n, px, py)
            if obj[k] != FREE or occ[k] > 0 or stamp[k] == tick:
                continue
            stamp[k] = tick
        xs[i] = nx
        ys[i] = ny
    recount(g, rb, run, r)


def warm_patches(g, run, r, x, y):
    """A prefetch of the field, object and occupancy patches a robot at Q8
    (x, y) reads on its turn (its patch's row and the rows beside it:
    probes, field, uphill). A row past the arena's edge is fetched too: a
    prefetch never faults, and the three rows need no bounds."""
    w = run.w[r]
    n = run.n[r]
    c = run.base[r] + cell(w, n, fx.patch(x), fx.patch(y))
    prefetch(g.field, c - n)
    prefetch(g.obj, c - n)
    prefetch(g.occ, c - n)
    prefetch(g.field, c)
    prefetch(g.obj, c)
    prefetch(g.occ, c)
    prefetch(g.field, c + n)
    prefetch(g.obj, c + n)
    prefetch(g.occ, c + n)


def warm_move(g, rb, run, r, i):
    """A prefetch of the cells robot i's move intent enters (apply_tick's
    reads of them): nothing when it has none. The cell is not folded onto
    the torus nor checked against the arena: a prefetch never faults, and
    a wrapping move's cell past the edge is only a useless fetch."""
    if rb.mv_on[i] == 0:
        return
    w = run.w[r]
    k = run.base[r] + cell(w, run.n[r], fx.patch(rb.xs[i] + step_dx(rb.mv_h[i], rb.mv_step[i])),
                           fx.patch(rb.ys[i] + step_dy(rb.mv_h[i], rb.mv_step[i])))
    prefetch(g.obj, k)
    prefetch(g.occ, k)
    prefetch(g.stamp, k)


def let_go(g, rb, run, r, i):
    """A robot that walks on (a forward intent, whether or not the move
    succeeds) lets go of the segment it held: it is free to claim again. The
    thesis's robots never walk while holding; a released holder does
    (RELEASE)."""
    k = run.base[r] + rb.held[i]
    rb.held[i] = -1
    g.obj[k] = YELLOW
    g.owner[k] = 0


def _carried(g, run, r, k):
    """1 if cell k (relative) is one of the carried object's cells."""
    w = run.w[r]
    n = run.n[r]
    cx = g.cx
    cy = g.cy
    for j in range(run.c0[r], run.c1[r]):
        if cell(w, n, cx[j], cy[j]) == k:
            return 1
    return 0


def _carrier(g, rb, run, r, j):
    """The robot holding carried cell j (c0 <= j < c1), -1 if none.

    A claimed cell's owner is its holder's node and a holder's `held` is
    that cell (claims, let_go, release and carry_group change both
    together; tests/test_kernel_invariants.py checks it every tick), so the
    carriers are found from the object's cells, not by a walk of every
    robot: at 10,000 robots the crowd rules ask this hundreds of times a
    step."""
    k = cell(run.w[r], run.n[r], g.cx[j], g.cy[j])
    node = g.owner[run.base[r] + k]
    lo = run.lo[r]
    if node > 0 and rb.held[lo + node - 1] == k:
        return lo + node - 1
    return -1


def _holder_at(g, rb, run, r, k):
    """1 if some holder of the carried object stands on cell k (relative)."""
    w = run.w[r]
    n = run.n[r]
    for j in range(run.c0[r], run.c1[r]):
        i = _carrier(g, rb, run, r, j)
        if i >= 0 and cell(w, n, fx.patch(rb.xs[i]), fx.patch(rb.ys[i])) == k:
            return 1
    return 0


def carry_beacons(g, rb, run, r):
    """The carriers' fields follow them one step (field DYNAMIC, thesis
    6.1.3: a beacon belongs to its robot, so no field stays behind)."""
    held = rb.held
    bsx = rb.bsx
    bsy = rb.bsy
    for i in range(run.lo[r], run.hi[r]):
        if held[i] < 0 or (rb.beacon_on[i] & EMITS) == 0 or not _carried(g, run, r, held[i]):
            continue
        ddx = rb.carry_dx[i]
        ddy = rb.carry_dy[i]
        if run.sigmode[r] == ON_PATCH:
            signal(g, run, r, bsx[i], bsy[i], -1)
            bsx[i] += ddx
            bsy[i] += ddy
            signal(g, run, r, bsx[i], bsy[i], 1)
        else:
            signal_at(g, run, r, bsx[i], bsy[i], -1)
            bsx[i] += ddx * fx.ONE
            bsy[i] += ddy * fx.ONE
            signal_at(g, run, r, bsx[i], bsy[i], 1)


def carry_group(g, rb, run, r):
    """Move the object with its holders when all of them ask for the same
    step; a holder's request stays until the group moves or is blocked.
    Holders of another object (a decoy) take no part. Returns 1 if it moved.
    The step tried is run.cdx[r], run.cdy[r]."""
    lo = run.lo[r]
    hi = run.hi[r]
    w = run.w[r]
    n = run.n[r]
    base = run.base[r]
    tick = run.tick[r]
    obj = g.obj
    owner = g.owner
    stamp = g.stamp
    cx = g.cx
    cy = g.cy
    c0 = run.c0[r]
    c1 = run.c1[r]
    xs = rb.xs
    ys = rb.ys
    held = rb.held
    holders = 0
    ddx = 0
    ddy = 0
    for i in range(lo, hi):
        if held[i] < 0 or not _carried(g, run, r, held[i]):
            continue
        if rb.carry_on[i] == 0:
            return 0                     # a holder that has not asked yet
        if holders > 0 and (rb.carry_dx[i] != ddx or rb.carry_dy[i] != ddy):
            return 0                     # holders disagree
        ddx = rb.carry_dx[i]
        ddy = rb.carry_dy[i]
        holders += 1
    if holders == 0:
        return 0
    for i in range(lo, hi):
        if held[i] >= 0:
            rb.carry_on[i] = 0           # consumed: moved or blocked
    run.cdx[r] = ddx
    run.cdy[r] = ddy
    for j in range(c0, c1):
        if _blocked(g, rb, run, r, cx[j] + ddx, cy[j] + ddy):
            return 0
    for i in range(lo, hi):
        if held[i] >= 0 and _carried(g, run, r, held[i]) and \
                _blocked(g, rb, run, r, fx.patch(xs[i]) + ddx, fx.patch(ys[i]) + ddy):
            return 0
    if (run.rules[r] & YIELD) != 0 and make_way(g, rb, run, r) == 0:
        return 0
    cv = g.cv
    cw = g.cw
    for j in range(c0, c1):
        k = base + cell(w, n, cx[j], cy[j])
        cv[j] = obj[k]
        cw[j] = owner[k]
        obj[k] = FREE
        owner[k] = 0
    for j in range(c0, c1):
        cx[j] += ddx
        cy[j] += ddy
        k = base + cell(w, n, cx[j], cy[j])
        obj[k] = cv[j]
        owner[k] = cw[j]
        stamp[k] = tick
    for i in range(lo, hi):
        # the cells moved already: a carried holder's cell is now one step on
        if held[i] >= 0 and _carried(g, run, r, held[i] + ddy * n + ddx):
            xs[i] += ddx * fx.ONE
            ys[i] += ddy * fx.ONE
            held[i] += ddy * n + ddx
            stamp[base + cell(w, n, fx.patch(xs[i]), fx.patch(ys[i]))] = tick
    return 1


def _blocked(g, rb, run, r, px, py):
    """Whether the carried group may not enter patch (px, py): off the arena,
    an obstacle or another object's segment, or (without crowd YIELD) a robot
    that does not hold the carried object stands there."""
    w = run.w[r]
    if not inside(w, px, py):
        return 1
    k = cell(w, run.n[r], px, py)
    base = run.base[r]
    if g.obj[base + k] != FREE and not _carried(g, run, r, k):
        return 1
    if (run.rules[r] & YIELD) == 0 and g.occ[base + k] > 0 and \
            not _holder_at(g, rb, run, r, k):
        return 1
    return 0


# -- the turn loops: a tick of each activation ----------------------------------------
# hal.turn(robot, i) steps robot i's FSM once on its body: the batch engine's
# one body (sim_backend/batch/body.py) or the reference engine's (engine.py).

def sync_tick(robots, hal, g, rb, run, r):
    """One synchronous tick of run r: every robot in node order starts its
    turn (start_turn) and steps against the tick-start world, its actions
    intents; then the tick's intents are applied (apply_tick)."""
    lo = run.lo[r]
    hi = run.hi[r]
    # a big run's robots stand anywhere in its grids, and its robot tables
    # stream through the cache every tick: the patches a turn reads would
    # miss (WARM_MIN); the rows stream in order and need no hint
    far = hi - WARM_ROW
    if hi - lo < WARM_MIN:
        far = lo
    for i in range(lo, hi):
        if i < far:
            warm_patches(g, run, r, rb.xs[i + WARM_ROW], rb.ys[i + WARM_ROW])
        start_turn(g, rb, run, r, i)
        hal.turn(robots[i], i)
    apply_tick(g, rb, run, r)


# -- sequential activation (scenario activation = "netlogo") -----------------
# NetLogo's `ask robots`: one robot at a time in a random order drawn every go
# iteration, each applying its actions at once so the next robot sees them
# (docs/tick-semantics.md, "Activation"). The synchronous tick above stays
# the default.

def go_iteration(robots, hal, g, rb, run, r):
    """One go iteration of run r, NetLogo's `ask robots`: each robot in a
    freshly drawn order (draw_order) takes its turn's steps (turn_steps),
    each applied at once (apply_robot); then the iteration's beacons and
    the carried group (end_iteration). The last robot in the order whose
    beacon turns on is go's `found` (set by the last LookForObject of the
    iteration): a robot's beacon call is its own turn's, and beacons change
    only at the iteration's end, so it is known once its turn is over.

    A claim is a touch: one more step grasps (LookForObject holds at once)
    and the turn ends (go's `if foundObject [ stop ]`); a robot that has
    just entered the multi-step state goes on with a whole cycle of it in
    the same turn (the thesis's go: its second `if`, reached in the same
    iteration after FindField)."""
    lo = run.lo[r]
    hi = run.hi[r]
    fs = run.field_state[r]
    for i in range(lo, hi):
        rb.beacon_set[i] = -1
    draw_order(rb, run, r)
    order = rb.order
    xs = rb.xs
    ys = rb.ys
    # a big run's robots and their patches are fetched ahead of their turns
    # (WARM_MIN): in a random order each turn's data is a cache miss
    far = hi - WARM_ROW
    if hi - lo < WARM_MIN:
        far = lo
    last = -1
    for j in range(lo, hi):
        if j < far:
            a = order[j + WARM_ROW]
            prefetch(robots, a)
            prefetch(hal, a)
            prefetch(xs, a)
            prefetch(ys, a)
            prefetch(rb.held, a)
            prefetch(rb.mv_on, a)
            prefetch(rb.mv_h, a)
            prefetch(rb.mv_step, a)
            prefetch(rb.claim, a)
            prefetch(rb.beacon_set, a)       # (beacon_on: read only after a beacon call)
            a = order[j + WARM_CELL]
            prefetch_held(robots, a)
            warm_patches(g, run, r, xs[a], ys[a])
        i = order[j]
        steps = turn_steps(run, r, robots[i].state)
        k = 0
        while k < steps:
            was = robots[i].state
            rb.mv_on[i] = 0
            rb.claim[i] = -1
            hal.turn(robots[i], i)
            claimed = rb.claim[i] >= 0
            if claimed or rb.mv_on[i] != 0:     # else apply_robot changes nothing
                apply_robot(g, rb, run, r, i)
            run.steps[r] += 1
            if claimed:
                steps = k + 2
            elif was != fs and robots[i].state == fs:
                steps = k + 1 + turn_steps(run, r, robots[i].state)
            k += 1
        if rb.beacon_set[i] >= 1 and rb.beacon_on[i] == 0:
            last = i
    end_iteration(g, rb, run, r, last)


def order_seed(seed):
    """Start of run `seed`'s activation-order stream (a 31-bit LCG as the
    tie stream, apart from every robot's own stream)."""
    return (seed * 48271 + 2718281) % TIE_MOD


def draw_order(rb, run, r):
    """A fresh random order of run r's robots lo..hi-1 into rb.order[lo:hi]
    (a Fisher-Yates shuffle drawn from the run's stream run.order_rng[r])."""
    lo = run.lo[r]
    hi = run.hi[r]
    order = rb.order
    for i in range(lo, hi):
        order[i] = i
    s = run.order_rng[r]
    j = hi - 1
    while j > lo:
        s = (s * TIE_MUL + TIE_ADD) % TIE_MOD
        k = lo + (s >> 8) % (j - lo + 1)
        t = order[j]
        order[j] = order[k]
        order[k] = t
        j -= 1
    run.order_rng[r] = s


def turn_steps(run, r, state):
    """FSM steps of a robot's turn in one go iteration, by its state when the
    turn starts: 1 + the behaviour's MULTI_STEP parameter in its MULTI_STEP
    state (the thesis's go: FollowField, then `repeat` that many
    RandomHead, then FindObject), else 1."""
    if state == run.field_state[r]:
        return 1 + run.extra_steps[r]
    return 1


def apply_robot(g, rb, run, r, i):
    """Apply robot i's claim and move at once, against the world as the
    robots before it left it: a move into another patch fails if that patch
    is off the arena, part of the object or holds a robot now."""
    base = run.base[r]
    obj = g.obj
    occ = g.occ
    k = rb.claim[i]
    rb.claim[i] = -1
    if k >= 0 and obj[base + k] == YELLOW:
        obj[base + k] = BLUE
        g.owner[base + k] = i - run.lo[r] + 1
        rb.held[i] = k
    if rb.mv_on[i] == 0:
        return
    rb.mv_on[i] = 0
    if rb.held[i] >= 0:
        let_go(g, rb, run, r, i)
    w = run.w[r]
    n = run.n[r]
    rules = run.rules[r]
    nx = fold_q8(w, n, rb.xs[i] + step_dx(rb.mv_h[i], rb.mv_step[i]), rules)
    ny = fold_q8(w, n, rb.ys[i] + step_dy(rb.mv_h[i], rb.mv_step[i]), rules)
    px = fx.patch(nx)
    py = fx.patch(ny)
    ox = fx.patch(rb.xs[i])
    oy = fx.patch(rb.ys[i])
    if px != ox or py != oy:
        if not inside(w, px, py):
            return
        k = base + cell(w, n, px, py)
        if obj[k] != FREE or occ[k] > 0:
            return
        occ[base + cell(w, n, ox, oy)] -= 1
        occ[k] += 1
    rb.xs[i] = nx
    rb.ys[i] = ny


def end_iteration(g, rb, run, r, last):
    """After every robot's turn: the beacons of the iteration (go's Signal
    after the ask; `last`, the last finder in the drawn order, -1: none), the
    carried group (with the arena's `rules`, as in apply_tick), occupancy
    recounted."""
    beacons_last(g, rb, run, r, last)
    if carry_group(g, rb, run, r) and (run.rules[r] & DYNAMIC) != 0:
        carry_beacons(g, rb, run, r)
    recount(g, rb, run, r)


# -- crowd "yield": robots in the carried group's way step aside -------------------

def _in_way(g, rb, run, r, px, py):
    """1 if patch (px, py) is one the carried group enters: a cell or a
    carrier's patch, one step (run.cdx, run.cdy) on."""
    ddx = run.cdx[r]
    ddy = run.cdy[r]
    c0 = run.c0[r]
    c1 = run.c1[r]
    for j in range(c0, c1):
        if g.cx[j] + ddx == px and g.cy[j] + ddy == py:
            return 1
    for j in range(c0, c1):
        i = _carrier(g, rb, run, r, j)
        if i >= 0 and fx.patch(rb.xs[i]) + ddx == px and fx.patch(rb.ys[i]) + ddy == py:
            return 1
    return 0


def _aside(g, rb, run, r, px, py):
    """The cell a robot on (px, py) steps aside to, -1 if none: the first
    neighbour (the carry's own direction first, then N, NE, E, ...) inside
    the arena, free of objects, held by no robot at the tick's start,
    entered or reserved by none this tick, and off the group's way."""
    w = run.w[r]
    n = run.n[r]
    base = run.base[r]
    tick = run.tick[r]
    stamp = g.stamp
    for j in range(9):
        if j == 0:
            qx = px + run.cdx[r]
            qy = py + run.cdy[r]
        else:
            qx = px + UPHILL_DX[j - 1]
            qy = py + UPHILL_DY[j - 1]
        if not inside(w, qx, qy):
            continue
        k = base + cell(w, n, qx, qy)
        if g.obj[k] != FREE or g.occ[k] > 0 or stamp[k] == tick or stamp[k] == -tick - 2:
            continue
        if _in_way(g, rb, run, r, qx, qy):
            continue
        return k
    return -1


def make_way(g, rb, run, r):
    """crowd "yield": every robot that does not carry the object and stands
    where the group goes (one step run.cdx, run.cdy on) steps aside
    (`_aside`), in node order. First every such robot reserves its patch; if
    one cannot, the reservations go and 0 is returned (the step is blocked);
    else they all move, and 1.

    `_in_way` looks at every cell and carrier of the group, so a robot is
    first tested against the box round the group's way (its cells and
    carriers one step on): outside it no robot is in the way. Reservations
    lie within CHAIN_DEPTH of a robot in the box, so only that margin is
    cleared."""
    w = run.w[r]
    n = run.n[r]
    base = run.base[r]
    lo = run.lo[r]
    hi = run.hi[r]
    tick = run.tick[r]
    stamp = g.stamp
    cx = g.cx
    cy = g.cy
    xs = rb.xs
    ys = rb.ys
    held = rb.held
    bx0 = w + 1
    bx1 = -w - 1
    by0 = w + 1
    by1 = -w - 1
    for j in range(run.c0[r], run.c1[r]):
        if cx[j] < bx0:
            bx0 = cx[j]
        if cx[j] > bx1:
            bx1 = cx[j]
        if cy[j] < by0:
            by0 = cy[j]
        if cy[j] > by1:
            by1 = cy[j]
    for i in range(lo, hi):
        if held[i] >= 0 and _carried(g, run, r, held[i]):
            px = fx.patch(xs[i])
            py = fx.patch(ys[i])
            if px < bx0:
                bx0 = px
            if px > bx1:
                bx1 = px
            if py < by0:
                by0 = py
            if py > by1:
                by1 = py
    bx0 += run.cdx[r]
    bx1 += run.cdx[r]
    by0 += run.cdy[r]
    by1 += run.cdy[r]
    # rb.near: the robots in the box widened by CHAIN_DEPTH, in node order
    # (then -1, if there is room), the only ones `_robot_at` looks at. That
    # box holds every patch `_chain` asks about, and every robot moved here
    # starts in it (a robot first moves from where it stood: in the box or
    # on a chain's patch), so the robot on an asked patch is always one of
    # them; a scan of the run's every robot per asked patch was ~4 % of a
    # 10,000-robot run's tick
    near = rb.near
    m = lo
    for i in range(lo, hi):
        px = fx.patch(xs[i])
        py = fx.patch(ys[i])
        if bx0 - CHAIN_DEPTH <= px and px <= bx1 + CHAIN_DEPTH and \
                by0 - CHAIN_DEPTH <= py and py <= by1 + CHAIN_DEPTH:
            near[m] = i
            m += 1
    if m < hi:
        near[m] = -1
    ok = 1
    reserved = 0
    for i in range(lo, hi):
        if held[i] >= 0 and _carried(g, run, r, held[i]):
            continue
        px = fx.patch(xs[i])
        py = fx.patch(ys[i])
        if px < bx0 or px > bx1 or py < by0 or py > by1:
            continue
        if not _in_way(g, rb, run, r, px, py):
            continue
        k = -1
        if held[i] < 0:                  # a holder of another object cannot yield
            k = _aside(g, rb, run, r, px, py)
            if k < 0:                    # hemmed in: push along the crowd
                k = _chain(g, rb, run, r, i, 0)
        if k < 0:
            ok = 0
            break
        stamp[k] = -tick - 2             # reserved
        reserved += 1
    if reserved > 0:
        for qy in range(by0 - CHAIN_DEPTH - 1, by1 + CHAIN_DEPTH + 2):
            for qx in range(bx0 - CHAIN_DEPTH - 1, bx1 + CHAIN_DEPTH + 2):
                if inside(w, qx, qy) and stamp[base + cell(w, n, qx, qy)] == -tick - 2:
                    stamp[base + cell(w, n, qx, qy)] = -1
    if ok == 0:
        return 0
    for i in range(lo, hi):
        if held[i] >= 0:
            continue
        px = fx.patch(xs[i])
        py = fx.patch(ys[i])
        if px < bx0 or px > bx1 or py < by0 or py > by1:
            continue
        if not _in_way(g, rb, run, r, px, py):
            continue
        k = _aside(g, rb, run, r, px, py)
        if k < 0:
            _chain(g, rb, run, r, i, 1)
            continue
        xs[i] += ((k - base) % n - w - px) * fx.ONE
        ys[i] += ((k - base) // n - w - py) * fx.ONE
        stamp[k] = tick
    return 1


def _robot_at(rb, run, r, px, py):
    """The first robot standing on (px, py), -1 if none or if it holds a
    segment (a holder never yields): of make_way's rb.near, where every
    robot that can stand there is."""
    for j in range(run.lo[r], run.hi[r]):
        i = rb.near[j]
        if i < 0:
            break
        if fx.patch(rb.xs[i]) == px and fx.patch(rb.ys[i]) == py:
            if rb.held[i] >= 0:
                return -1
            return i
    return -1


def _chain(g, rb, run, r, mover, move):
    """crowd "yield" for robot `mover` when every neighbour of its patch
    (px, py) off the group's way is taken (a crowd two or more deep): the
    shortest push along the crowd, breadth first and at most CHAIN_DEPTH
    patches long. Each patch of the chain lies off the way and holds one
    robot that holds nothing; every robot on it steps one patch on, the last
    into a free patch (as `_aside` would take it). move 0 reserves the
    chain's patches, move 1 makes the moves and stamps them entered; either
    way the free patch's cell is returned, -1 if there is no such chain.

    The search marks its patches in `stamp` (values below the reserved
    -tick - 2: level * 8 + the UPHILL index of the step that reached it)
    and clears them before it returns."""
    w = run.w[r]
    n = run.n[r]
    base = run.base[r]
    tick = run.tick[r]
    stamp = g.stamp
    xs = rb.xs
    ys = rb.ys
    px = fx.patch(xs[mover])
    py = fx.patch(ys[mover])
    p = cell(w, n, px, py)
    end = -1
    end_d = 0
    level = 1
    while level <= CHAIN_DEPTH and end < 0:
        grew = 0
        for qy in range(py - level, py + level + 1):
            if end >= 0:
                break
            for qx in range(px - level, px + level + 1):
                if not inside(w, qx, qy):
                    continue
                k = base + cell(w, n, qx, qy)
                if stamp[k] == tick or stamp[k] <= -tick - 2 or g.obj[k] != FREE or \
                        (qx == px and qy == py):
                    continue
                d = _chain_parent(g, run, r, p, k - base, level)
                if d < 0 or _in_way(g, rb, run, r, qx, qy):
                    continue
                if g.occ[k] == 0:
                    end = k
                    end_d = d
                    break
                if g.occ[k] == 1 and level < CHAIN_DEPTH and \
                        _robot_at(rb, run, r, qx, qy) >= 0:
                    stamp[k] = -tick - 3 - (level * 8 + d)
                    grew = 1
        if grew == 0:
            break
        level += 1
    if end >= 0:
        # back from the free patch to (px, py): each robot steps into its child
        k = end
        qx = (end - base) % n - w
        qy = (end - base) // n - w
        d = end_d
        while True:
            sx = qx - UPHILL_DX[d]
            sy = qy - UPHILL_DY[d]
            if move == 1:
                i = mover
                if sx != px or sy != py:
                    i = _robot_at(rb, run, r, sx, sy)
                xs[i] += (qx - sx) * fx.ONE
                ys[i] += (qy - sy) * fx.ONE
                stamp[k] = tick
            else:
                stamp[k] = -tick - 2
            if sx == px and sy == py:
                break
            k = base + cell(w, n, sx, sy)
            d = (-tick - 3 - stamp[k]) % 8
            qx = sx
            qy = sy
    for qy in range(py - CHAIN_DEPTH, py + CHAIN_DEPTH + 1):
        for qx in range(px - CHAIN_DEPTH, px + CHAIN_DEPTH + 1):
            if inside(w, qx, qy) and stamp[base + cell(w, n, qx, qy)] < -tick - 2:
                stamp[base + cell(w, n, qx, qy)] = -1
    return end


def _chain_parent(g, run, r, p, q, level):
    """The UPHILL index of the step into patch q (a relative cell) from a
    neighbour the chain search reached at level - 1 (patch p itself, the
    mover's, at level 1), the first in N, NE, E, ... order; -1 if none."""
    w = run.w[r]
    n = run.n[r]
    tick = run.tick[r]
    px = p % n - w
    py = p // n - w
    qx = q % n - w
    qy = q // n - w
    for d in range(8):
        sx = qx - UPHILL_DX[d]
        sy = qy - UPHILL_DY[d]
        if level == 1:
            if sx == px and sy == py:
                return d
            continue
        if not inside(w, sx, sy):
            continue
        v = g.stamp[run.base[r] + cell(w, n, sx, sy)]
        if v < -tick - 2 and (-tick - 3 - v) // 8 == level - 1:
            return d
    return -1
