"""The world's rules, written once: sensing, claims, beacons, the carried
group, moves and occupancy (docs/tick-semantics.md).

Every function works on flat integer arrays: Python lists when the
reference engine (sim_backend/engine.py) interprets them for one run,
numpy arrays when the batch engine (sim_backend/batch/) compiles this very
source with numba for many runs at once. So the code keeps to what both
understand: ints, indexing, loops, calls to the functions here and in
firmware_logic/fixedpoint.py; no sets, dicts, tuples of tuples or
allocation.

Layout of one run inside the arrays:
    grids (obj, owner, field, occ, stamp): the run's n x n patches start at
        `base`; a patch (px, py) is cell (py + w) * n + (px + w), where
        w is the run's worldSize and n = 2w + 1; `held`, `claim` and the
        object cells hold cells relative to `base`;
    robots (xs, ys and every per-robot array): indices lo..hi-1, in node
        order, so robot i is node i - lo + 1;
    the object's cells: cx, cy from c0 to c1 (cv, cw are scratch);
    the Signal table (tdx, tdy, tv): entries t0 to t1.
"""

from firmware_logic import fixedpoint as fx
from firmware_logic.hal import BEACON_LEADER, CLAIMED, NOTHING, OBJECT, ROBOT, WALL

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


def ahead_x(x, h):
    """Patch column one patch ahead of Q8 x along heading h."""
    return fx.patch(x + fx.dx(h, fx.ONE))


def ahead_y(y, h):
    return fx.patch(y + fx.dy(h, fx.ONE))


def ahead_cell(w, n, x, y, h, rules):
    """Cell (relative) of the patch one ahead along h, wrapped when the run
    wraps: the patch a probe saw, which a claim takes."""
    return cell(w, n, fold(w, n, ahead_x(x, h), rules), fold(w, n, ahead_y(y, h), rules))


# -- sensing: the world as it stood at the start of the tick ------------------

def probe(obj, occ, base, w, n, x, y, h, rules):
    px = fold(w, n, ahead_x(x, h), rules)
    py = fold(w, n, ahead_y(y, h), rules)
    if not inside(w, px, py):
        return WALL
    k = base + cell(w, n, px, py)
    o = obj[k]
    if o == OBSTACLE:
        return WALL
    if o == YELLOW:
        return OBJECT
    if o == BLUE:
        return CLAIMED
    c = occ[k]
    if px == fx.patch(x) and py == fx.patch(y) and (rules & SELF_COUNTS) == 0:
        c -= 1               # the robot itself (a turn within its own patch)
    if c > 0:
        return ROBOT
    return NOTHING


def field_ahead(field, base, w, n, x, y, h, rules):
    px = fold(w, n, ahead_x(x, h), rules)
    py = fold(w, n, ahead_y(y, h), rules)
    if not inside(w, px, py):
        return 0
    return field[base + cell(w, n, px, py)]


def field_here(field, base, w, n, x, y):
    return field[base + cell(w, n, fx.patch(x), fx.patch(y))]


def tie_seed(seed, node):
    """Start of robot `node`'s uphill tie stream in run `seed`."""
    return (seed * 7919 + node * 104729 + 1) % TIE_MOD


def uphill(field, base, w, n, x, y, ties, tie, i, rules):
    """Heading to the strongest neighbour if stronger than here, else -1.

    Ties (ties == ORDERED) go to the first in N, NE, E, ... order; with
    AT_RANDOM one of the tied neighbours is drawn from robot i's stream
    tie[i], as NetLogo's uphill draws `random.nextInt(winners.size)` among
    the neighbours of the greatest value (prim/etc HillCommand, NetLogo
    sources), moving only if that value is greater than here."""
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
    if ties == ORDERED:
        return aim(x, y, px, py, out // 45, rules)
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


def holding(owner, base, held, node):
    if held >= 0 and owner[base + held] == node:
        return 1
    return 0


# -- the field --------------------------------------------------------------------

def signal(field, base, w, n, tdx, tdy, tv, t0, t1, px, py, sign, rules):
    """Add (sign 1) or remove (sign -1) one beacon's field centred on a patch
    (on the torus when the run wraps: sigRadius <= worldSize, so no patch is
    reached twice)."""
    for t in range(t0, t1):
        x = fold(w, n, px + tdx[t], rules)
        y = fold(w, n, py + tdy[t], rules)
        if inside(w, x, y):
            field[base + cell(w, n, x, y)] += sign * tv[t]


def signal_value(d2):
    """round(10 / (1 + d)) for d = sqrt(d2) / fx.ONE, halves rounded up, in
    integers: the value is the number of k in 0..9 with 10 / (1 + d) >= k + 1/2,
    that is d <= (19 - 2k) / (2k + 1), so no float rounding can differ
    between the engines."""
    v = 0
    for k in range(10):
        a = 19 - 2 * k
        b = 2 * k + 1
        if d2 * b * b <= a * a * fx.ONE * fx.ONE:
            v += 1
    return v


def signal_at(field, base, w, n, radius, x, y, sign, rules):
    """Signal as Appendix A writes it, centred on the Q8 position (x, y):
    every patch within `radius` of the patch holding it (`patches in-radius`,
    by patch centres) gets round(10 / (1 + d)), d its centre's distance from
    the position itself (`distancexy tempx tempy`); NetLogo rounds halves up."""
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


def beacons(field, base, w, n, tdx, tdy, tv, t0, t1, xs, ys, lo, hi, beacon_set,
            beacon_on, bsx, bsy, sigmode, radius, rules):
    """Beacons turned on or off this tick, then every leader's pinned patch.

    BEACON_ON lights a beacon, BEACON_LEADER a leader's (it pins its patch to
    LEADER_FIELD every tick, Appendix A go's `set field 10`). ON_PATCH: each
    beacon turned on adds the Signal table centred on its robot's patch.
    LAST_FINDER: only the highest node turning on this tick signals (go
    calls Signal once, for the global `found`'s last setter), centred on its
    Q8 position. A beacon turned off takes its field with it (our addition).
    Pins come before the new fields, as go's ask precedes its Signal."""
    last = -1
    for i in range(lo, hi):
        b = beacon_set[i]
        if b >= 1 and beacon_on[i] == 0:
            last = i
    beacons_last(field, base, w, n, tdx, tdy, tv, t0, t1, xs, ys, lo, hi, beacon_set,
                 beacon_on, bsx, bsy, sigmode, radius, last, rules)


def beacons_last(field, base, w, n, tdx, tdy, tv, t0, t1, xs, ys, lo, hi, beacon_set,
                 beacon_on, bsx, bsy, sigmode, radius, last, rules):
    """`beacons` with the last finder given (robot index, -1: none)."""
    for i in range(lo, hi):
        b = beacon_set[i]
        if b == 0 and beacon_on[i] != 0:
            if beacon_on[i] & EMITS:
                # our addition: a beacon switched off takes its field with it
                if sigmode == ON_PATCH:
                    signal(field, base, w, n, tdx, tdy, tv, t0, t1, bsx[i], bsy[i], -1,
                           rules)
                else:
                    signal_at(field, base, w, n, radius, bsx[i], bsy[i], -1, rules)
            beacon_on[i] = 0
    for i in range(lo, hi):
        if (beacon_on[i] & PINS) or (beacon_set[i] == BEACON_LEADER and beacon_on[i] == 0):
            field[base + cell(w, n, fx.patch(xs[i]), fx.patch(ys[i]))] = LEADER_FIELD
    for i in range(lo, hi):
        b = beacon_set[i]
        if b < 1 or beacon_on[i] != 0:
            continue
        pins = PINS if b == BEACON_LEADER else 0
        if sigmode == ON_PATCH:
            bsx[i] = fx.patch(xs[i])
            bsy[i] = fx.patch(ys[i])
            beacon_on[i] = EMITS | pins
            signal(field, base, w, n, tdx, tdy, tv, t0, t1, bsx[i], bsy[i], 1, rules)
        elif i == last:
            bsx[i] = xs[i]
            bsy[i] = ys[i]
            beacon_on[i] = EMITS | pins
            signal_at(field, base, w, n, radius, bsx[i], bsy[i], 1, rules)
        else:
            beacon_on[i] = pins


def recount(occ, base, w, n, xs, ys, lo, hi):
    for k in range(base, base + n * n):
        occ[k] = 0
    for i in range(lo, hi):
        occ[base + cell(w, n, fx.patch(xs[i]), fx.patch(ys[i]))] += 1


# -- applying one tick's intents ---------------------------------------------------

def apply_tick(obj, owner, field, occ, stamp, base, w, n, tdx, tdy, tv, t0, t1,
               xs, ys, lo, hi, held, mv_on, mv_h, mv_step, claim, beacon_set,
               beacon_on, bsx, bsy, carry_on, carry_dx, carry_dy,
               cx, cy, cv, cw, c0, c1, tick, sigmode, radius, rules):
    """Apply every robot's intents of tick `tick` (>= 1) in the fixed order:
    claims (lowest node wins a segment), beacons, the carried group, moves in
    node order; then recount occupancy. `stamp` marks the patches entered
    this tick with the tick number. The carried object is the one whose
    cells are cx, cy (c0..c1); other objects and obstacles stay put.
    rules: DYNAMIC, the carriers' beacons move with them; YIELD, robots in
    the carried object's way step aside."""
    for i in range(lo, hi):
        k = claim[i]
        if k >= 0 and obj[base + k] == YELLOW:
            obj[base + k] = BLUE
            owner[base + k] = i - lo + 1
            held[i] = k
    beacons(field, base, w, n, tdx, tdy, tv, t0, t1, xs, ys, lo, hi, beacon_set,
            beacon_on, bsx, bsy, sigmode, radius, rules)
    if carry_group(obj, owner, occ, stamp, base, w, n, xs, ys, lo, hi, held,
                   carry_on, carry_dx, carry_dy, cx, cy, cv, cw, c0, c1, tick, rules) \
            and (rules & DYNAMIC) != 0:
        carry_beacons(field, base, w, n, tdx, tdy, tv, t0, t1, lo, hi, held, beacon_on,
                      bsx, bsy, cx, cy, c0, c1, carry_dx, carry_dy, sigmode, radius, rules)
    for i in range(lo, hi):
        if mv_on[i] == 0:
            continue
        if held[i] >= 0:
            let_go(obj, owner, base, held, i)
        nx = fold_q8(w, n, xs[i] + fx.dx(mv_h[i], mv_step[i]), rules)
        ny = fold_q8(w, n, ys[i] + fx.dy(mv_h[i], mv_step[i]), rules)
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
    recount(occ, base, w, n, xs, ys, lo, hi)


def let_go(obj, owner, base, held, i):
    """A robot that walks on (a forward intent, whether or not the move
    succeeds) lets go of the segment it held: it is free to claim again. The
    thesis's robots never walk while holding; a released holder does
    (RELEASE, issue 13 §2)."""
    k = base + held[i]
    held[i] = -1
    obj[k] = YELLOW
    owner[k] = 0


def _carried(w, n, cx, cy, c0, c1, k):
    """1 if cell k (relative) is one of the carried object's cells."""
    for j in range(c0, c1):
        if cell(w, n, cx[j], cy[j]) == k:
            return 1
    return 0


def _carrier(owner, base, w, n, lo, held, cx, cy, j):
    """The robot holding carried cell j (c0 <= j < c1), -1 if none.

    A claimed cell's owner is its holder's node and a holder's `held` is
    that cell (claims, let_go, faults.release and carry_group change both
    together; tests/test_kernel_invariants.py checks it every tick), so the
    carriers are found from the object's cells, not by a walk of every
    robot: at 10,000 robots the crowd rules ask this hundreds of times a
    step."""
    k = cell(w, n, cx[j], cy[j])
    node = owner[base + k]
    if node > 0 and held[lo + node - 1] == k:
        return lo + node - 1
    return -1


def _holder_at(owner, base, w, n, xs, ys, lo, held, cx, cy, c0, c1, k):
    """1 if some holder of the carried object stands on cell k (relative)."""
    for j in range(c0, c1):
        i = _carrier(owner, base, w, n, lo, held, cx, cy, j)
        if i >= 0 and cell(w, n, fx.patch(xs[i]), fx.patch(ys[i])) == k:
            return 1
    return 0


def carry_beacons(field, base, w, n, tdx, tdy, tv, t0, t1, lo, hi, held, beacon_on,
                  bsx, bsy, cx, cy, c0, c1, carry_dx, carry_dy, sigmode, radius, rules):
    """The carriers' fields follow them one step (field DYNAMIC, thesis
    6.1.3: a beacon belongs to its robot, so no field stays behind)."""
    for i in range(lo, hi):
        if held[i] < 0 or (beacon_on[i] & EMITS) == 0 or not _carried(w, n, cx, cy, c0, c1,
                                                                         held[i]):
            continue
        ddx = carry_dx[i]
        ddy = carry_dy[i]
        if sigmode == ON_PATCH:
            signal(field, base, w, n, tdx, tdy, tv, t0, t1, bsx[i], bsy[i], -1, rules)
            bsx[i] += ddx
            bsy[i] += ddy
            signal(field, base, w, n, tdx, tdy, tv, t0, t1, bsx[i], bsy[i], 1, rules)
        else:
            signal_at(field, base, w, n, radius, bsx[i], bsy[i], -1, rules)
            bsx[i] += ddx * fx.ONE
            bsy[i] += ddy * fx.ONE
            signal_at(field, base, w, n, radius, bsx[i], bsy[i], 1, rules)


def carry_group(obj, owner, occ, stamp, base, w, n, xs, ys, lo, hi, held,
                carry_on, carry_dx, carry_dy, cx, cy, cv, cw, c0, c1, tick, rules):
    """Move the object with its holders when all of them ask for the same
    step; a holder's request stays until the group moves or is blocked.
    Holders of another object (a decoy) take no part. Returns 1 if it moved."""
    holders = 0
    ddx = 0
    ddy = 0
    for i in range(lo, hi):
        if held[i] < 0 or not _carried(w, n, cx, cy, c0, c1, held[i]):
            continue
        if carry_on[i] == 0:
            return 0                     # a holder that has not asked yet
        if holders > 0 and (carry_dx[i] != ddx or carry_dy[i] != ddy):
            return 0                     # holders disagree
        ddx = carry_dx[i]
        ddy = carry_dy[i]
        holders += 1
    if holders == 0:
        return 0
    for i in range(lo, hi):
        if held[i] >= 0:
            carry_on[i] = 0              # consumed: moved or blocked
    crowd = 0
    if (rules & YIELD) != 0:
        crowd = 1
    for j in range(c0, c1):
        if _blocked(obj, owner, occ, base, w, n, xs, ys, lo, held, cx, cy, c0, c1,
                    cx[j] + ddx, cy[j] + ddy, crowd):
            return 0
    for i in range(lo, hi):
        if held[i] >= 0 and _carried(w, n, cx, cy, c0, c1, held[i]) and \
                _blocked(obj, owner, occ, base, w, n, xs, ys, lo, held, cx, cy, c0, c1,
                         fx.patch(xs[i]) + ddx, fx.patch(ys[i]) + ddy, crowd):
            return 0
    if crowd == 1 and make_way(obj, owner, occ, stamp, base, w, n, xs, ys, lo, hi, held,
                               cx, cy, c0, c1, ddx, ddy, tick) == 0:
        return 0
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
        if held[i] >= 0 and _carried(w, n, cx, cy, c0, c1, held[i] + ddy * n + ddx):
            xs[i] += ddx * fx.ONE
            ys[i] += ddy * fx.ONE
            held[i] += ddy * n + ddx
            stamp[base + cell(w, n, fx.patch(xs[i]), fx.patch(ys[i]))] = tick
    return 1


def _blocked(obj, owner, occ, base, w, n, xs, ys, lo, held, cx, cy, c0, c1, px, py, crowd):
    """Whether the carried group may not enter patch (px, py): off the arena,
    an obstacle or another object's segment, or (crowd 0) a robot that does
    not hold the carried object stands there."""
    if not inside(w, px, py):
        return 1
    k = cell(w, n, px, py)
    if obj[base + k] != FREE and not _carried(w, n, cx, cy, c0, c1, k):
        return 1
    if crowd == 0 and occ[base + k] > 0 and \
            not _holder_at(owner, base, w, n, xs, ys, lo, held, cx, cy, c0, c1, k):
        return 1
    return 0


# -- sequential activation (scenario activation = "netlogo") -----------------
# NetLogo's `ask robots`: one robot at a time in a random order drawn every go
# iteration, each applying its actions at once so the next robot sees them
# (docs/tick-semantics.md, "Activation"). The synchronous tick above stays
# the default; these functions are the sequential one's rules, used by both
# engines (sim_backend/engine.py, sim_backend/batch/body.py).

SYNC = 0            # activation: every robot decides on the tick-start world
SEQUENTIAL = 1      # activation: NetLogo's ask, one robot after another


def order_seed(seed):
    """Start of run `seed`'s activation-order stream (a 31-bit LCG as the
    tie stream, apart from every robot's own stream)."""
    return (seed * 48271 + 2718281) % TIE_MOD


def draw_order(order, lo, hi, state, r):
    """A fresh random order of robots lo..hi-1 into order[lo:hi] (a
    Fisher-Yates shuffle drawn from the run's stream state[r])."""
    for i in range(lo, hi):
        order[i] = i
    s = state[r]
    j = hi - 1
    while j > lo:
        s = (s * TIE_MUL + TIE_ADD) % TIE_MOD
        k = lo + (s >> 8) % (j - lo + 1)
        t = order[j]
        order[j] = order[k]
        order[k] = t
        j -= 1
    state[r] = s


def turn_steps(state, multi_state, extra):
    """FSM steps of a robot's turn in one go iteration, by its state when the
    turn starts: 1 + the behaviour's MULTI_STEP parameter in its MULTI_STEP
    state (the thesis's go: FollowField, then `repeat` that many
    RandomHead, then FindObject), else 1."""
    if state == multi_state:
        return 1 + extra
    return 1


def turn_length(steps, k, claimed, was, state, multi_state, extra):
    """The turn's length after its step k (0-based), which took the robot
    from state `was` to `state`. A claim is a touch: one more step grasps
    (LookForObject holds at once) and the turn ends (go's `if foundObject
    [ stop ]`); a robot that has just entered the multi-step state goes on with a
    whole cycle of it in the same turn (the thesis's go: its second `if`,
    reached in the same iteration after FindField)."""
    if claimed:
        return k + 2
    if was != multi_state and state == multi_state:
        return k + 1 + turn_steps(state, multi_state, extra)
    return steps


def apply_robot(obj, owner, occ, base, w, n, xs, ys, lo, i, held, mv_on, mv_h, mv_step,
                claim, rules):
    """Apply robot i's claim and move at once, against the world as the
    robots before it left it: a move into another patch fails if that patch
    is off the arena, part of the object or holds a robot now."""
    k = claim[i]
    claim[i] = -1
    if k >= 0 and obj[base + k] == YELLOW:
        obj[base + k] = BLUE
        owner[base + k] = i - lo + 1
        held[i] = k
    if mv_on[i] == 0:
        return
    mv_on[i] = 0
    if held[i] >= 0:
        let_go(obj, owner, base, held, i)
    nx = fold_q8(w, n, xs[i] + fx.dx(mv_h[i], mv_step[i]), rules)
    ny = fold_q8(w, n, ys[i] + fx.dy(mv_h[i], mv_step[i]), rules)
    px = fx.patch(nx)
    py = fx.patch(ny)
    ox = fx.patch(xs[i])
    oy = fx.patch(ys[i])
    if px != ox or py != oy:
        if not inside(w, px, py):
            return
        k = base + cell(w, n, px, py)
        if obj[k] != FREE or occ[k] > 0:
            return
        occ[base + cell(w, n, ox, oy)] -= 1
        occ[k] += 1
    xs[i] = nx
    ys[i] = ny


def last_finder(order, lo, hi, beacon_set, beacon_on):
    """The last robot in this iteration's order whose beacon turns on (go's
    `found`, set by the last LookForObject of the iteration), -1 if none."""
    last = -1
    for j in range(lo, hi):
        i = order[j]
        if beacon_set[i] >= 1 and beacon_on[i] == 0:
            last = i
    return last


def end_iteration(obj, owner, field, occ, stamp, base, w, n, tdx, tdy, tv, t0, t1,
                  xs, ys, lo, hi, held, beacon_set, beacon_on, bsx, bsy, carry_on,
                  carry_dx, carry_dy, cx, cy, cv, cw, c0, c1, tick, sigmode, radius,
                  order, rules):
    """After every robot's turn: the beacons of the iteration (go's Signal
    after the ask; the last finder in the drawn order), the carried group
    (with the arena's `rules`, as in apply_tick), occupancy recounted."""
    beacons_last(field, base, w, n, tdx, tdy, tv, t0, t1, xs, ys, lo, hi, beacon_set,
                 beacon_on, bsx, bsy, sigmode, radius,
                 last_finder(order, lo, hi, beacon_set, beacon_on), rules)
    if carry_group(obj, owner, occ, stamp, base, w, n, xs, ys, lo, hi, held,
                   carry_on, carry_dx, carry_dy, cx, cy, cv, cw, c0, c1, tick, rules) \
            and (rules & DYNAMIC) != 0:
        carry_beacons(field, base, w, n, tdx, tdy, tv, t0, t1, lo, hi, held, beacon_on,
                      bsx, bsy, cx, cy, c0, c1, carry_dx, carry_dy, sigmode, radius, rules)
    recount(occ, base, w, n, xs, ys, lo, hi)


def _in_way(owner, base, w, n, xs, ys, lo, held, cx, cy, c0, c1, ddx, ddy, px, py):
    """1 if patch (px, py) is one the carried group enters: a cell or a
    carrier's patch, one step (ddx, ddy) on."""
    for j in range(c0, c1):
        if cx[j] + ddx == px and cy[j] + ddy == py:
            return 1
    for j in range(c0, c1):
        i = _carrier(owner, base, w, n, lo, held, cx, cy, j)
        if i >= 0 and fx.patch(xs[i]) + ddx == px and fx.patch(ys[i]) + ddy == py:
            return 1
    return 0


def _aside(obj, owner, occ, stamp, base, w, n, xs, ys, lo, held, cx, cy, c0, c1, ddx, ddy,
           tick, px, py):
    """The cell a robot on (px, py) steps aside to, -1 if none: the first
    neighbour (the carry's own direction first, then N, NE, E, ...) inside
    the arena, free of objects, held by no robot at the tick's start,
    entered or reserved by none this tick, and off the group's way."""
    for j in range(9):
        if j == 0:
            qx = px + ddx
            qy = py + ddy
        else:
            qx = px + UPHILL_DX[j - 1]
            qy = py + UPHILL_DY[j - 1]
        if not inside(w, qx, qy):
            continue
        k = base + cell(w, n, qx, qy)
        if obj[k] != FREE or occ[k] > 0 or stamp[k] == tick or stamp[k] == -tick - 2:
            continue
        if _in_way(owner, base, w, n, xs, ys, lo, held, cx, cy, c0, c1, ddx, ddy, qx, qy):
            continue
        return k
    return -1


def make_way(obj, owner, occ, stamp, base, w, n, xs, ys, lo, hi, held, cx, cy, c0, c1,
             ddx, ddy, tick):
    """crowd "yield": every robot that does not carry the object and stands
    where the group goes steps aside (`_aside`), in node order. First every
    such robot reserves its patch; if one cannot, the reservations go and 0
    is returned (the step is blocked); else they all move, and 1.

    `_in_way` looks at every cell and carrier of the group, so a robot is
    first tested against the box round the group's way (its cells and
    carriers one step on): outside it no robot is in the way. Reservations
    lie within CHAIN_DEPTH of a robot in the box, so only that margin is
    cleared."""
    bx0 = w + 1
    bx1 = -w - 1
    by0 = w + 1
    by1 = -w - 1
    for j in range(c0, c1):
        if cx[j] < bx0:
            bx0 = cx[j]
        if cx[j] > bx1:
            bx1 = cx[j]
        if cy[j] < by0:
            by0 = cy[j]
        if cy[j] > by1:
            by1 = cy[j]
    for i in range(lo, hi):
        if held[i] >= 0 and _carried(w, n, cx, cy, c0, c1, held[i]):
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
    bx0 += ddx
    bx1 += ddx
    by0 += ddy
    by1 += ddy
    ok = 1
    reserved = 0
    for i in range(lo, hi):
        if held[i] >= 0 and _carried(w, n, cx, cy, c0, c1, held[i]):
            continue
        px = fx.patch(xs[i])
        py = fx.patch(ys[i])
        if px < bx0 or px > bx1 or py < by0 or py > by1:
            continue
        if not _in_way(owner, base, w, n, xs, ys, lo, held, cx, cy, c0, c1, ddx, ddy, px, py):
            continue
        k = -1
        if held[i] < 0:                  # a holder of another object cannot yield
            k = _aside(obj, owner, occ, stamp, base, w, n, xs, ys, lo, held, cx, cy, c0, c1,
                       ddx, ddy, tick, px, py)
            if k < 0:                    # hemmed in: push along the crowd
                k = _chain(obj, owner, occ, stamp, base, w, n, xs, ys, lo, hi, held, cx, cy,
                           c0, c1, ddx, ddy, tick, px, py, i, 0)
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
        if not _in_way(owner, base, w, n, xs, ys, lo, held, cx, cy, c0, c1, ddx, ddy, px, py):
            continue
        k = _aside(obj, owner, occ, stamp, base, w, n, xs, ys, lo, held, cx, cy, c0, c1,
                   ddx, ddy, tick, px, py)
        if k < 0:
            _chain(obj, owner, occ, stamp, base, w, n, xs, ys, lo, hi, held, cx, cy, c0, c1,
                   ddx, ddy, tick, px, py, i, 1)
            continue
        xs[i] += ((k - base) % n - w - px) * fx.ONE
        ys[i] += ((k - base) // n - w - py) * fx.ONE
        stamp[k] = tick
    return 1


def _robot_at(xs, ys, lo, hi, held, px, py):
    """The first robot standing on (px, py), -1 if none or if it holds a
    segment (a holder never yields)."""
    for i in range(lo, hi):
        if fx.patch(xs[i]) == px and fx.patch(ys[i]) == py:
            if held[i] >= 0:
                return -1
            return i
    return -1


def _chain(obj, owner, occ, stamp, base, w, n, xs, ys, lo, hi, held, cx, cy, c0, c1, ddx,
           ddy, tick, px, py, mover, move):
    """crowd "yield" for robot `mover` on (px, py) when every neighbour off
    the group's way is taken (a crowd two or more deep): the shortest push
    along the crowd, breadth first and at most CHAIN_DEPTH patches long. Each
    patch of the chain lies off the way and holds one robot that holds
    nothing; every robot on it steps one patch on, the last into a free
    patch (as `_aside` would take it). move 0 reserves the chain's patches,
    move 1 makes the moves and stamps them entered; either way the free
    patch's cell is returned, -1 if there is no such chain.

    The search marks its patches in `stamp` (values below the reserved
    -tick - 2: level * 8 + the UPHILL index of the step that reached it)
    and clears them before it returns."""
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
                if stamp[k] == tick or stamp[k] <= -tick - 2 or obj[k] != FREE or \
                        (qx == px and qy == py):
                    continue
                d = _chain_parent(stamp, base, w, n, tick, px, py, qx, qy, level)
                if d < 0 or _in_way(owner, base, w, n, xs, ys, lo, held, cx, cy, c0, c1, ddx,
                                    ddy, qx, qy):
                    continue
                if occ[k] == 0:
                    end = k
                    end_d = d
                    break
                if occ[k] == 1 and level < CHAIN_DEPTH and \
                        _robot_at(xs, ys, lo, hi, held, qx, qy) >= 0:
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
                    i = _robot_at(xs, ys, lo, hi, held, sx, sy)
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


def _chain_parent(stamp, base, w, n, tick, px, py, qx, qy, level):
    """The UPHILL index of the step into (qx, qy) from a neighbour the chain
    search reached at level - 1 ((px, py) itself at level 1), the first in
    N, NE, E, ... order; -1 if none."""
    for d in range(8):
        sx = qx - UPHILL_DX[d]
        sy = qy - UPHILL_DY[d]
        if level == 1:
            if sx == px and sy == py:
                return d
            continue
        if not inside(w, sx, sy):
            continue
        v = stamp[base + cell(w, n, sx, sy)]
        if v < -tick - 2 and (-tick - 3 - v) // 8 == level - 1:
            return d
    return -1
