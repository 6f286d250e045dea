"""The host coordinator of the centralised phase, as pure logic.

It is fed decoded messages (node, kind, fields) by whatever link carries them
and returns the commands to send. It keeps the touch set, the power held
against the object's weight, the leader (first finder), plans the transport
toward home and detects arrival. Only robots that hold the object are
commanded (the thesis's flaw of 6.1.2, redirecting every robot, is fixed).

Time is the caller's tick counter; nothing here reads a clock.

Nothing a robot (or anything else on the bus) sends is trusted: a report is
checked against what the host knows (docs/protocol.md, "Valid reports")
BEFORE it is journalled, because a journalled report is replayed by every
resumed host; a report that fails is dropped, counted in `rejected` by
reason, passed to `on_reject` (the host process logs it) and not ACKed.
"""

from firmware_logic import messages as msg
from firmware_logic.roster import BAD_HELLO, CHANGED_HELLO, Roster  # noqa: F401 (re-exported)
from firmware_logic.roster import STALLED as STALLED_OUTCOME
from . import spec
from .recognising import Recognising

RESEND_AFTER = 4   # ticks without progress before a command is sent again
STALL_TICKS = 2000  # transport ticks without the object moving before the run stops
# steps the object moves (each way) before a plan measures again which points
# can be nearest home (`_within`): few enough that the points it ruled out
# stay out, enough that measuring is rare
NEAR_STEPS = 8

# why a run stopped without delivering (Coordinator.stop_code; 0: it did not)
NO_PATH = 1
STALLED = 2
STOP_REASONS = ("", "no path home", "stalled")
# host-side logic: portable, but allowed to allocate
SUBSET_SETUP = ("Touch", "Coordinator", "way_home", "_free", "_nearest", "_closer", "_closer_h",
                "_squares", "_within", "_ranked", "_box_of", "_grown")
STEPS = ((-1, -1), (-1, 0), (0, -1), (1, -1), (-1, 1), (1, 0), (0, 1), (1, 1))


# reasons a report is rejected (keys of Coordinator.rejected)
UNANNOUNCED_TOUCH = "touch from unannounced node"
UNANNOUNCED_HEARTBEAT = "heartbeat from unannounced node"
OUTSIDE = "outside the arena"
NOT_ADJACENT = "segment not next to the robot"
NOT_OBJECT = "segment not on the object"
AT_HOME = "segment at home"
WRONG_POWER = "power differs from HELLO"
SECOND_TOUCH = "second touch from node"
CLAIMED = "segment held by another robot"
LEADER_JUMP = "leader pose does not follow the step"
# the movement model codes a HELLO may announce: the spec's
MODELS = ()
for _code, _name in spec.MODELS:
    MODELS = MODELS + (_code,)

# a patch coordinate travels in one signed byte: the arena of a host that was
# not told its size
BYTE_ARENA = 127


def way_home(w, footprint, blocked, goal_pts, home_x, home_y, home_r2, start, slack=2,
             avoid=None):
    """wayHome over the configuration space of the object's whole footprint
    (thesis 6.1.4, 6.2.4): {(dx, dy): steps} for every displacement of the
    footprint (object cells and carriers, absolute cells at displacement
    (0, 0)) that keeps it inside the arena -w..w and off every `blocked` cell,
    counted in 8-neighbour steps (the transport's) from the displacements
    where a `goal_pts` point lies within home_r2 of home. A breadth-first
    search from the goal that stops `slack` layers after reaching `start`
    (no path: `start` is missing). avoid: displacements to leave out (steps
    the transport tried and found blocked). Plain lists and dicts: it runs on the
    host, in CPython and MicroPython."""
    x0 = x1 = footprint[0][0]
    y0 = y1 = footprint[0][1]
    for p in footprint:
        x0 = min(x0, p[0])
        x1 = max(x1, p[0])
        y0 = min(y0, p[1])
        y1 = max(y1, p[1])
    box = (-w - x0, w - x1, -w - y0, w - y1)
    ok = {}
    if avoid:
        for d in avoid:
            ok[d] = False

    dist = {}
    frontier = []
    r = 0
    while r * r < home_r2:
        r += 1
    for gx, gy in goal_pts:
        for a in range(-r, r + 1):
            for b in range(-r, r + 1):
                if a * a + b * b < home_r2:
                    d = (home_x + a - gx, home_y + b - gy)
                    if d not in dist and _free(d, box, footprint, blocked, ok):
                        dist[d] = 0
                        frontier.append(d)
    level = 0
    stop = -1
    while frontier:
        if start in dist and stop < 0:
            stop = dist[start] + slack
        if stop >= 0 and level >= stop:
            break
        level += 1
        nxt = []
        for d in frontier:
            for sx, sy in STEPS:
                e = (d[0] + sx, d[1] + sy)
                if e not in dist and _free(e, box, footprint, blocked, ok):
                    dist[e] = level
                    nxt.append(e)
        frontier = nxt
    return dist


def _free(d, box, footprint, blocked, ok):
    """Whether displacement d keeps the footprint in `box` and off `blocked`
    (memoised in ok)."""
    v = ok.get(d)
    if v is None:
        v = box[0] <= d[0] <= box[1] and box[2] <= d[1] <= box[3]
        if v and blocked:
            for p in footprint:
                if (p[0] + d[0], p[1] + d[1]) in blocked:
                    v = False
                    break
        ok[d] = v
    return v


def _nearest(rel):
    """The points of `rel` (less home) that can be nearest home after a step
    of at most one patch each way: every point whose least possible squared
    distance after any such step, |p|^2 - 2(|x| + |y|), is within the
    largest possible one of some point, |p|^2 + 2(|x| + |y|) + 2. The least
    distance after each step is the same over these as over all (the plan
    asks it for nine steps, of up to every holder's point)."""
    if len(rel) < 4:
        return rel
    top = -1
    for x, y in rel:
        a = (x if x >= 0 else -x) + (y if y >= 0 else -y)
        u = x * x + y * y + 2 * a + 2
        if top < 0 or u < top:
            top = u
    out = []
    for x, y in rel:
        a = (x if x >= 0 else -x) + (y if y >= 0 else -y)
        if x * x + y * y - 2 * a <= top:
            out.append((x, y))
    return out


def _least_d2(pts, cx, cy):
    """The least x * x + y * y of the points `pts` displaced by (cx, cy); -1
    when there are none."""
    best = -1
    for x, y in pts:
        x += cx
        y += cy
        d = x * x + y * y
        if best < 0 or d < best:
            best = d
    return best


def _closer(pts, mx, my):
    """The steps of STEPS that bring the least x * x + y * y of the points
    `pts` displaced by (mx, my) below where it is, best first: (that least
    distance, the order among them, dx, dy), ties to the earlier step."""
    return _closer_h(pts, mx, my)[1]


def _closer_h(pts, mx, my):
    """(`_least_d2(pts, mx, my)`, `_closer(pts, mx, my)`)."""
    sq = _squares(pts, mx, my)
    return _ranked(sq, mx, my, _within(sq, mx, my) if sq else [], 0)


def _squares(pts, mx, my):
    """The points as `_ranked` reads them, (x * x + y * y, 2x, 2y, n) each:
    first the one nearest (-mx, -my), with n 0, then the others with n =
    2(|x - x0| + |y - y0|) from that one (x0, y0)."""
    sq = []
    k = -1
    best = 0
    for x, y in pts:
        s = x * x + y * y
        e = s + 2 * (x * mx + y * my)        # |p + m|^2 less |m|^2
        if k < 0 or e < best:
            best = e
            k = len(sq)
        sq.append((s, x, y))
    if k < 0:
        return []
    s, x0, y0 = sq[k]
    out = [(s, x0 + x0, y0 + y0, 0)]
    i = 0
    for s, x, y in sq:
        if i != k:
            n = (x - x0 if x >= x0 else x0 - x) + (y - y0 if y >= y0 else y0 - y)
            out.append((s, x + x, y + y, n + n))
        i += 1
    return out


def _within(sq, mx, my):
    """The points of `sq` (`_squares`') but the first as (r, s, 2x, 2y, n),
    least r first: at every displacement within r steps each way of (mx,
    my) the point is nowhere nearer than the first one after a step, so a
    plan from there skips it unseen (r -1: it may be nearer now; the first
    point's copies, n 0, never are and are left out). The point's e (see
    `_ranked`) less the first's moves by at most n per step, and it is
    nowhere nearer while that difference is n or more."""
    out = []
    s, tx, ty, n = sq[0]
    es = s + tx * mx + ty * my
    for s, tx, ty, n in sq:
        if n:
            d = s + tx * mx + ty * my - es - n
            out.append((d // n if d >= 0 else -1, s, tx, ty, n))
    out.sort()
    return out


def _ranked(sq, mx, my, near, steps):
    """`_closer_h` of the points whose `_squares` are sq, displaced by (mx,
    my); near: `_within(sq, ax, ay)` for a displacement (ax, ay) at most
    `steps` steps each way from (mx, my).

    When `near` rules every other point out, the first point p alone
    decides: a step v takes it to |p|^2 + 2p.v + |v|^2. Else one pass: |q +
    m + v|^2 = e + 2q.v + |m + v|^2 with e = |q|^2 + 2q.m, and the last term
    is the same for every point q: the least e + 2q.v for the nine steps v
    come by sums alone, and |m + v|^2 is added to the nine minima once. The
    first point seeds them; of the others only those `near` has not ruled
    out are read, and of those any whose e is the first's plus n or more is
    skipped (2q.v differs by at most n between them: it is nowhere
    nearer). In a transport the first point decides nearly every plan
    alone."""
    if not sq:
        return -1, []
    s, tx, ty, n = sq[0]
    if not near or near[0][0] >= steps:
        u = tx + mx + mx                 # 2p
        w = ty + my + my
        h = (u * u + w * w) >> 2
        a = h - u + 1                    # x - 1
        b = h + u + 1                    # x + 1
        d0 = a - w + 1                   # STEPS' order
        d1 = a
        d2 = h - w + 1
        d3 = b - w + 1
        d4 = a + w + 1
        d5 = b
        d6 = h + w + 1
        d7 = b + w + 1
    else:
        es = s + tx * mx + ty * my
        a = es - tx
        b = es + tx
        h = es
        a0 = a - ty
        a1 = a
        a2 = es - ty
        a3 = b - ty
        a4 = a + ty
        a5 = b
        a6 = es + ty
        a7 = b + ty
        for r, s, tx, ty, n in near:
            if r >= steps:
                break
            e = s + tx * mx + ty * my
            if e - es >= n:
                continue
            if e < h:
                h = e
            a = e - tx
            b = e + tx
            d = a - ty
            if d < a0:
                a0 = d
            if a < a1:
                a1 = a
            d = e - ty
            if d < a2:
                a2 = d
            d = b - ty
            if d < a3:
                a3 = d
            d = a + ty
            if d < a4:
                a4 = d
            if b < a5:
                a5 = b
            d = e + ty
            if d < a6:
                a6 = d
            d = b + ty
            if d < a7:
                a7 = d
        x = mx * mx              # |m + v|^2 from mx^2, (mx - 1)^2, (mx + 1)^2 ...
        y = my * my
        xm = x - mx - mx + 1
        xp = x + mx + mx + 1
        ym = y - my - my + 1
        yp = y + my + my + 1
        h += x + y
        d0 = a0 + xm + ym
        d1 = a1 + xm + y
        d2 = a2 + x + ym
        d3 = a3 + xp + ym
        d4 = a4 + xm + yp
        d5 = a5 + xp + y
        d6 = a6 + x + yp
        d7 = a7 + xp + yp
    ranked = []                  # STEPS unrolled: a loop over them cost a quarter of a plan
    if d0 < h:
        ranked.append((d0, len(ranked), -1, -1))
    if d1 < h:
        ranked.append((d1, len(ranked), -1, 0))
    if d2 < h:
        ranked.append((d2, len(ranked), 0, -1))
    if d3 < h:
        ranked.append((d3, len(ranked), 1, -1))
    if d4 < h:
        ranked.append((d4, len(ranked), -1, 1))
    if d5 < h:
        ranked.append((d5, len(ranked), 1, 0))
    if d6 < h:
        ranked.append((d6, len(ranked), 0, 1))
    if d7 < h:
        ranked.append((d7, len(ranked), 1, 1))
    ranked.sort()
    return h, ranked


def _box_of(pts):
    """(x0, x1, y0, y1) round the points, or None when there are none."""
    return None if pts is None else _grown(None, pts)


def _grown(box, pts):
    """`box` (None: no box yet) grown to hold every point of `pts`, in one
    pass (a call per point cost a rebuild of `_held` a fifth of its time);
    None when both are empty."""
    if box is None:
        for x, y in pts:
            box = (x, x, y, y)
            break
        else:
            return None
    x0, x1, y0, y1 = box
    for x, y in pts:
        if x < x0:
            x0 = x
        elif x > x1:
            x1 = x
        if y < y0:
            y0 = y
        elif y > y1:
            y1 = y
    if box[0] == x0 and box[1] == x1 and box[2] == y0 and box[3] == y1:
        return box
    return x0, x1, y0, y1


class Touch:
    def __init__(self, node, seq, rx, ry, sx, sy, power, tick, mx=0, my=0):
        """rx..sy in the object's frame; (mx, my) is how far the object had
        moved when the touch was accepted, so the report as the robot sent it
        (and retransmits it) is rx + mx, ... (`report`)."""
        self.node = node
        self.seq = seq
        self.rx = rx
        self.ry = ry
        self.sx = sx
        self.sy = sy
        self.power = power
        self.tick = tick
        self.mx = mx
        self.my = my

    def as_tuple(self):
        return (self.node, self.seq, self.rx, self.ry, self.sx, self.sy,
                self.power, self.tick)

    def report(self):
        """The TOUCH fields (seq, rx, ry, sx, sy, power) as the robot sent them."""
        return (self.seq, self.rx + self.mx, self.ry + self.my,
                self.sx + self.mx, self.sy + self.my, self.power)



class Coordinator(Recognising, Roster):
    NOT_SNAPSHOT = Roster.NOT_SNAPSHOT + ("home_x", "home_y", "home_r2", "by_carrier",
                                          "closed", "stall_ticks", "cells_box",
                                          "leader_heard", "held") \
        + Recognising.RECOGNITION_NOT_SNAPSHOT
    VOLATILE = ("step_sent_tick",)     # a resend of the same TRANSPORT

    def __init__(self, weight, home_x=-15, home_y=-15, home_radius=4, journal=None,
                 world_size=None, cells=None, on_reject=None, by_carrier=False,
                 blocked=None, stall_ticks=STALL_TICKS, lost_after=0, crowd_yields=False):
        """weight: the object's weight in hundredths (objectWeight * 100).

        journal: optional callable(node, kind, fields, tick) called for every
        report that changed what the host knows (a HELLO of a new node, an
        accepted TOUCH, a leader HEARTBEAT that moved the object during the
        transport) BEFORE it is acknowledged (the host process makes it
        durable; firmware_logic/roster.py). on_reject: optional
        callable(reason, node, fields).
        world_size: patches run from -world_size to +world_size (None: only
        what a byte carries). cells: the object's cells where it starts, when
        the host knows them (a simulation); None: any cell is plausible.
        blocked: the cells the object may not enter (obstacles, other
        objects), when the host has a map; then the transport follows
        `way_home` round them, else the straight gradient of PaintHome's
        wayHome (the thesis's, kept bit for bit in an open arena).
        stall_ticks: transport ticks without the object moving before the
        run stops as stalled.
        lost_after: ticks of silence after which a holder is lost (0: never,
        the thesis's host); see `_liveness` and docs/extensions.md.
        crowd_yields: the world's crowd rule is "yield" (bystanders, the dead
        among them, step aside for the carried object), so a lost holder's
        cell is not an obstacle to plan round; False: "block".
        """
        Roster.__init__(self, MODELS, journal, on_reject)
        self.closed = None if blocked is None else frozenset(blocked)
        self.stall_ticks = stall_ticks
        self.stopped_tick = -1   # stopped without delivering, stop_code says why
        self.stop_code = 0
        self.last_move_tick = -1
        self.way = None          # way_home's field, from the displacement way_from
        self.way_from = (0, 0)
        self.weight = weight
        self.home_x = home_x
        self.home_y = home_y
        self.home_r2 = home_radius * home_radius
        # arrival: False, a carrier or segment within home_radius (the
        # project's default, 4); True, only carriers count and the plan
        # brings the nearest carrier home (Appendix A writes tt.txt when a
        # holder is within 1 of home; scenario arrival = "netlogo")
        self.by_carrier = by_carrier
        self.world_size = BYTE_ARENA if world_size is None else world_size
        self.cells = None if cells is None else frozenset(cells)
        self.cells_box = None if cells is None else _box_of(self.cells)
        self.touches = []        # accepted, in order of acceptance
        # node -> its accepted Touch: one touch per node per object (a robot
        # never releases the object), so the node identifies the touch and a
        # retransmission is the same report again
        self.by_node = {}
        self.power = 0
        self.leader = 0
        self.found_tick = -1
        self.converged_tick = -1
        self.delivered_tick = -1
        self.duplicates = 0
        self.outbox = []
        # TOUCHes heard while a transport step is under way, judged at the
        # tick's end (`_touch_waiting`): (node, fields) in the order heard
        self.waiting = []
        # transport
        self.step = 0
        self.step_sent_tick = -1
        self.leader_x = 0        # leader pose, patches
        self.leader_y = 0
        self.leader_done = 0
        # the fields of the leader's last HEARTBEAT that left its pose as
        # above: a repeat changes nothing (muted)
        self.leader_heard = None
        self.moved_x = 0         # object displacement since the touches
        self.moved_y = 0
        self.blocked = 0
        self.planned_from = (0, 0)
        self.dx = 0
        self.dy = 0
        self.halted = 0
        # liveness (lost_after > 0): holders dropped as silent, and where each
        # stood (x, y pairs, flat), an obstacle from then on; both journalled
        # with the decision that dropped it, so a resumed host agrees
        self.lost_after = lost_after
        self.crowd_yields = crowd_yields
        self.lost = ()
        self.lost_cells = ()
        self.heard = {}          # node -> (tick, moved_x, moved_y) when last heard
        # displacements a transport step was blocked at (x, y pairs, flat):
        # the plan goes round them (dead robots stand still; see _bump)
        self.bumps = ()
        self.held = None             # `_held`'s, kept between plans
        self.setup_recognition()     # off; recognition() turns it on

    # -- input -------------------------------------------------------------

    def on_message(self, node, kind, f, tick):
        if self.lost_after and node in self.nodes:
            self.heard[node] = (tick, self.moved_x, self.moved_y)
        # HEARTBEAT first: nearly every message a transport hears
        if kind == msg.HEARTBEAT:
            if node not in self.nodes:
                self._reject(UNANNOUNCED_HEARTBEAT, node, f)
                return
            if self.recognise:           # a call saved per message otherwise
                self._seen(node, f)
            if node == self.leader and self.step > 0:
                x = (f[1] + 128) >> 8
                y = (f[2] + 128) >> 8
                lx = self.leader_x
                ly = self.leader_y
                if x == lx and y == ly and f[4] == self.leader_done:
                    self.leader_heard = tuple(f)
                    return
                # the leader moves with the object, at most one patch per
                # step commanded since its last pose here (and the step it
                # had reported may have moved it since): a jump is not it
                k = (self.step - self.leader_done) % 255 + 1
                if x - lx > k or lx - x > k or y - ly > k or ly - y > k:
                    self._reject(LEADER_JUMP, node, f)
                    return
                # the object moved (or a step is done): a later touch is
                # stored in the frame this sets, so a resumed host needs it
                self._record(node, kind, f, tick)
                self.leader_x = x
                self.leader_y = y
                self.leader_done = f[4]
                self.leader_heard = tuple(f)
                lead = self.by_node.get(node)    # leader_touch(): its call saved per step
                self.moved_x = x - lead.rx
                self.moved_y = y - lead.ry
        elif kind == msg.HELLO:
            self._hello(node, f, tick)
        elif kind == msg.TOUCH:
            if self.step != self.leader_done or self.waiting:
                # The object may have moved at the last tick's end, and the
                # leader's HEARTBEAT saying where it is now may come later
                # among this tick's messages (NetLogo's random turn order):
                # judged now, the touch would be placed on the object from
                # where the object was, at the cell of another holder or
                # off the object, and its robot, refused, would hold the
                # object still forever (docs/tick-semantics.md, "A touch
                # during the transport"). Once one waits, the tick's later
                # touches wait behind it: they are accepted in the order heard.
                self.waiting.append((node, f))
                return
            self._touch(node, f, tick)
        else:
            self._reject("unexpected kind %d from a robot" % kind, node, f)

    def _touch(self, node, f, tick):
        t = self.by_node.get(node)
        if t is not None:
            # before the checks: a retransmission repeats the report as it was
            # sent, in the frame of a then unmoved object
            if t.report() == tuple(f):
                self.duplicates += 1
                self._ack(node, f[0])        # the first ACK may have been lost
            else:
                # one touch per node: a second report (a new seq, or the same
                # seq about another segment) is a forgery or a fault; it
                # neither counts twice nor turns the real one into a duplicate
                self._reject(SECOND_TOUCH, node, f, msg.TOUCH)
            return
        why = self._invalid_touch(node, f, self.moved_x, self.moved_y)
        if why is not None:
            self._reject(why, node, f, msg.TOUCH)
            if (why == CLAIMED or why == AT_HOME) and self.converged_tick >= 0:
                # the segment is the carried object's as the host sees it,
                # but this touch never counts: its robot, never commanded,
                # would hold the object still for good (the world moves it
                # only when every holder carries); told to let go, it
                # leaves that segment alone for spec.RELEASE_TICKS. (Before
                # the transport nothing moves: an honest robot is refused
                # on the object only where no mission would have started.)
                self._send(node, spec.RELEASE, (f[3], f[4], f[3], f[4]))
            return
        # stored in the object's frame: it may have moved since the start
        t = Touch(node, f[0], f[1] - self.moved_x, f[2] - self.moved_y,
                  f[3] - self.moved_x, f[4] - self.moved_y, f[5], tick,
                  self.moved_x, self.moved_y)
        self._record(node, msg.TOUCH, f, tick)
        self._adopt(t)
        self._ack(node, f[0])
        self._stray(t, tick)

    def _touch_waiting(self, tick):
        """Judge the TOUCHes heard during a transport step, in the order
        heard, once every message of their tick is in: a robot's report is
        of the world as its tick began, which the leader's HEARTBEAT of the
        same tick tells (the object moves only at a tick's end, and not at
        all while a robot holds it unannounced: carry_group waits for every
        holder). Dated now: the journal holds it from here, after the
        reports that set its frame, and a replay judges it at once."""
        waiting = self.waiting
        self.waiting = []
        for node, f in waiting:
            self._touch(node, f, tick)

    def _invalid_touch(self, node, f, mx, my):
        """Why the TOUCH fields f (world frame, the object displaced by
        (mx, my)) from `node` are not a valid report, or None."""
        known = self.nodes.get(node)
        if known is None:
            return UNANNOUNCED_TOUCH      # its power is unknown: wait for HELLO
        rx, ry, sx, sy = f[1], f[2], f[3], f[4]
        w = self.world_size
        if not (-w <= rx <= w and -w <= ry <= w and -w <= sx <= w and -w <= sy <= w):
            return OUTSIDE
        ddx = sx - rx
        ddy = sy - ry
        if ddx < -1 or ddx > 1 or ddy < -1 or ddy > 1 or (ddx == 0 and ddy == 0):
            return NOT_ADJACENT
        if self.cells is not None and (sx - mx, sy - my) not in self.cells:
            return NOT_OBJECT
        for t in self.touches:
            # one robot holds a segment (the world's claim has one owner); a
            # lost holder let go of its own
            if t.sx == sx - mx and t.sy == sy - my and t.node not in self.lost:
                return CLAIMED
        hx = sx - self.home_x
        hy = sy - self.home_y
        if hx * hx + hy * hy < self.home_r2:
            # an object there is home already: no mission would have started
            return AT_HOME
        if f[5] != known[1]:
            return WRONG_POWER
        return None

    def _adopt(self, t):
        self.by_node[t.node] = t
        self.touches.append(t)
        self.power += t.power
        if self.found_tick < 0 or t.tick < self.found_tick:
            self.found_tick = t.tick
        if self.leader == 0:
            self.leader = t.node
            self.leader_x = t.rx
            self.leader_y = t.ry

    def _send(self, node, kind, fields):
        self.outbox.append((node, kind, fields))

    # -- the host's tick ---------------------------------------------------------

    def carriers(self):
        return list(self._held()[7])

    def _held(self):
        """What a plan reads of the touches, in the object's frame (as before
        it moved), kept between plans: (touches, the last touch, their
        count, lost, body, the points that count for arrival (`_from_home`'s),
        the live holders' points, the live holders (`carriers`), the box
        round `_footprint()` or None, `_home_reached`'s bound: while the
        least squared distance of a segment is at least this, no live holder
        is within home_radius, and `_rank`'s [`_squares`, `_within`, at mx, my]
        of the arrival points). A touch is appended when accepted and removed
        when released, and `lost` and `body` are replaced whole when they
        change, so the first five say whether it still holds."""
        h = self.held
        touches = self.touches
        last = touches[-1] if touches else None
        if h is not None and h[0] is touches and h[1] is last and h[2] == len(touches) \
                and h[3] is self.lost and h[4] is self.body:
            return h
        lost = self.lost
        segs = []
        live = []
        nodes = []
        g = 0                        # the farthest a live holder stands from its segment, per axis
        for t in touches:
            sx = t.sx
            sy = t.sy
            segs.append((sx, sy))
            node = t.node
            if node not in lost:
                rx = t.rx
                ry = t.ry
                live.append((rx, ry))
                if node not in nodes:
                    nodes.append(node)
                # max and abs without their calls: a rebuild per touch accepted
                d = rx - sx if rx >= sx else sx - rx
                if d > g:
                    g = d
                d = ry - sy if ry >= sy else sy - ry
                if d > g:
                    g = d
        if self.cells is not None:
            box = self.cells_box
        else:
            box = _grown(None, segs) if self.body is None else _box_of(self.body)
        box = _grown(box, live)
        # a holder stands within g * sqrt(2) of its own segment, so none is
        # within sqrt(r2) while every segment is at least sqrt(r2) +
        # g * sqrt(2) away: r2 + 2 * g * sqrt(2 * r2) + 2 * g * g, with
        # q >= sqrt(2 * r2) keeping it integer and never below that (r2 is
        # home_radius squared: a few steps, once per change of holders)
        r2 = self.home_r2
        q = 0
        while q * q < 2 * r2:
            q += 1
        pts = live if self.by_carrier else segs
        mx = self.moved_x - self.home_x
        my = self.moved_y - self.home_y
        sq = _squares(pts, mx, my)
        h = (touches, last, len(touches), lost, self.body, pts, live, tuple(nodes), box,
             r2 + 2 * g * q + 2 * g * g, [sq, _within(sq, mx, my) if sq else [], mx, my])
        self.held = h
        return h

    def _rank(self, h):
        """`_closer_h` of the arrival points where they are now (relative to
        home), from `_held()` h's `_within`, measured again once the object
        is more than NEAR_STEPS steps each way from where it was measured:
        further on, more of the points it rules out come back."""
        c = h[10]
        mx = self.moved_x - self.home_x
        my = self.moved_y - self.home_y
        d = mx - c[2] if mx >= c[2] else c[2] - mx
        e = my - c[3] if my >= c[3] else c[3] - my
        if e > d:
            d = e
        if d > NEAR_STEPS and c[0]:
            c[1] = _within(c[0], mx, my)
            c[2] = mx
            c[3] = my
            d = 0
        return _ranked(c[0], mx, my, c[1], d)

    def decision(self, before, out):
        """The thesis names its decisions: converged, step, delivered, halt."""
        if self.delivered_tick != before["delivered_tick"]:
            return "delivered", "object home; HALT"
        if self.stopped_tick != before.get("stopped_tick", -1):
            return "stopped", self.status() + "; HALT"
        if list(self.lost) != before.get("lost", []):
            return "lost", ("holders lost %s; power %d/%d; leader robot %d"
                            % (list(self.lost), self.power, self.weight, self.leader))
        if self.converged_tick != before["converged_tick"]:
            return "converged", ("converged, power %d/%d; leader robot %d; transport begins"
                                 % (self.power, self.weight, self.leader))
        if self.step != before["step"]:
            return "step", "transport step %d (%+d, %+d)" % (self.step, self.dx, self.dy)
        for m in out:
            if m[1] == msg.HALT:
                return "halt", ""
        return None

    def done(self):
        return self.delivered_tick >= 0 or self.stopped_tick >= 0

    def ended(self):
        """The roster's outcome; a transport that stopped moving is STALLED."""
        if self.delivered_tick < 0 and self.stopped_tick >= 0 and self.stop_code == STALLED:
            return STALLED_OUTCOME
        return Roster.ended(self)

    def measures(self):
        """Why the run ended or where it stands (RunResult.summary's `outcome`),
        and what recognition decided when it is on."""
        out = self.recognition_measures()
        if self.delivered_tick >= 0:
            out["outcome"] = "delivered"
        elif self.stopped_tick >= 0:
            out["outcome"] = STOP_REASONS[self.stop_code]
        elif self.converged_tick >= 0:
            out["outcome"] = "transporting"
        else:
            out["outcome"] = "collecting touches"
        return out

    def status(self):
        if self.stopped_tick >= 0:
            return "stopped at tick %d: %s" % (self.stopped_tick, STOP_REASONS[self.stop_code])
        if self.delivered_tick >= 0:
            return "delivered at tick %d" % self.delivered_tick
        if self.converged_tick >= 0:
            return "transport step %d (leader done %d)" % (self.step, self.leader_done)
        # power and weight are hundredths: say them in weight units, as the
        # live view's bar and the summary do
        return "collecting touches, power %d.%02d of weight %d.%02d" % (
            self.power // 100, self.power % 100, self.weight // 100, self.weight % 100)

    def segments_now(self):
        """Touched segments where they are now (they move with the object)."""
        out = []
        for t in self.touches:
            out.append((t.sx + self.moved_x, t.sy + self.moved_y))
        return out

    def quiet(self):
        """True when tick() without a new message would neither send nor change
        anything (a batch engine then skips the call): before convergence
        with power short of the weight, and after the HALT went out."""
        if self.converged_tick >= 0 and not self.done():
            return False             # a transport: asked after every tick (the rest says so too)
        if self.outbox or self.acks or self.waiting:
            return False
        if self.done():
            return self.halted == 1
        if self.lost_after and self.touches:
            return False             # a holder's silence is counted every tick
        if self.recognise and self.converged_tick < 0 and self.touches:
            return False             # a verdict may come with no new message
        return self.converged_tick < 0 and not (self.touches and self.power >= self.weight)

    def muted(self):
        """(kind, nodes, but, same): the messages of that kind from the nodes
        in `nodes` (a collection that only grows) other than node `but`, and
        `but`'s with the fields `same`, would change nothing until the next
        tick() (a batch engine then does not hand them over; a message taken
        in between never makes one of them count, but one from `but` with
        other fields ends `same`), or None. Here the HEARTBEATs of announced
        holders, and the transport leader's that repeat the last one that
        set its pose, unless liveness or recognition read them."""
        if self.lost_after or self.recognise:
            return None
        if self.step == 0:
            return msg.HEARTBEAT, self.nodes, 0
        f = self.leader_heard
        if f is not None and ((f[1] + 128) >> 8 != self.leader_x
                              or (f[2] + 128) >> 8 != self.leader_y
                              or f[4] != self.leader_done):
            f = None                  # the pose came from elsewhere (an adopted snapshot)
        return msg.HEARTBEAT, self.nodes, self.leader, f

    def idle_until(self):
        """The first tick whose tick() may change anything or send when no
        message comes before it (0: any): while the transport waits for the
        leader to report a step, the step's resend and the stall."""
        if self.outbox or self.acks or self.waiting or self.lost_after or self.recognise \
                or self.done() or self.converged_tick < 0 or self.power < self.weight \
                or self.last_move_tick < 0 or self.leader_done == self.step:
            return 0
        t = self.step_sent_tick + RESEND_AFTER
        s = self.last_move_tick + self.stall_ticks
        return t if t < s else s

    def tick(self, tick):
        """Advance the centralised phase; return and clear the commands to send."""
        if self.waiting:
            self._touch_waiting(tick)
        if self.acks:                    # a transport tick has none
            self._acks_out(self.outbox)
        done = self.done()               # liveness changes holders, not this
        if self.lost_after and not done:
            self._liveness(tick)
        if done:
            if not self.halted:
                self.halted = 1
                self._send(msg.HOST, msg.HALT, (0,))
        elif self.converged_tick < 0:
            if self._ready(tick):
                self.converged_tick = tick
                self._plan_step(tick)
        else:
            self._transport(tick)
        out = self.outbox
        self.outbox = []
        return out

    def _transport(self, tick):
        if self.power < self.weight:
            # holders were lost: the transport pauses (no command; the stall
            # clock starts again when it goes on) while the swarm converges
            # on the object again
            self.last_move_tick = -1
            return
        if self.last_move_tick < 0:
            self.last_move_tick = tick
        if tick - self.last_move_tick >= self.stall_ticks:
            self._stop(tick, STALLED)
            return
        if self.leader_done == self.step:
            if self.moved_x == self.planned_from[0] and self.moved_y == self.planned_from[1]:
                self.blocked += 1
                if self.lost_after:
                    self._bump()
            else:
                self.blocked = 0
                self.last_move_tick = tick
            h = self._held()             # read once for both
            plan = None
            if self.closed is None and not self.lost_cells and not self.bumps:
                # the open arena's plan measures where the points are now
                # too: arrival reads that instead of a pass of its own
                plan = self._rank(h)
            if self._home_reached(h, -2 if plan is None else plan[0]):
                self.delivered_tick = tick
                self.halted = 1
                self._send(msg.HOST, msg.HALT, (0,))
                return
            self._plan_step(tick, h, plan)
        elif tick - self.step_sent_tick >= RESEND_AFTER:
            self._command(tick)

    def reporters(self):
        """spec.REPORTERS by name, for the per-tick trace."""
        return {"holders": len(self.carriers()), "home_d2": self._home_d2(0, 0)}

    def leader_touch(self):
        return self.by_node.get(self.leader)     # one touch per node, as in touches

    def _points_now(self):
        """Segments and carriers where they are now."""
        return self.segments_now() + self._carriers_now()

    def _carriers_now(self):
        out = []
        for t in self.touches:
            if t.node not in self.lost:
                out.append((t.rx + self.moved_x, t.ry + self.moved_y))
        return out

    def _home_d2(self, ddx, ddy, rel=None):
        """The least squared distance to home of a point that counts for
        arrival, displaced by (ddx, ddy); -1 without one. rel: those points
        less home (`_from_home`), when the caller has them already."""
        if rel is None:
            rel = self._from_home()
        return _least_d2(rel, ddx, ddy)

    def _from_home(self):
        """The points that count for arrival (carriers when by_carrier, else
        segments) where they are now, less home."""
        mx = self.moved_x - self.home_x
        my = self.moved_y - self.home_y
        out = []
        for x, y in self._held()[5]:
            out.append((x + mx, y + my))
        return out

    def _home_reached(self, h=None, near=-2):
        """h: `_held()`, when the caller has it; near: `_least_d2` of its
        arrival points where they are now, when the caller has it (-2: not)."""
        # ours: a robot or a segment within 4 of home (`wayHome < 4` only
        # sets canTransport in Appendix A); by_carrier: a robot within
        # home_radius, as the thesis's tt.txt (`distancexy -15 -15 < 1`)
        mx = self.moved_x - self.home_x
        my = self.moved_y - self.home_y
        r2 = self.home_r2
        if h is None:
            h = self._held()
        d = _least_d2(h[5], mx, my) if near == -2 else near
        if 0 <= d < r2:
            return True
        if h[6] is h[5] or d >= h[9]:
            return False                 # the live holders are those, or all too far
        d = _least_d2(h[6], mx, my)      # the live holders
        return 0 <= d < r2

    def _stop(self, tick, code):
        """End the mission without delivering: HALT every robot."""
        self.stopped_tick = tick
        self.stop_code = code
        self.halted = 1
        self._send(msg.HOST, msg.HALT, (0,))

    def _footprint(self):
        """The object's cells (its true ones when known, else the touched
        segments) and its carriers, where they are now."""
        cells = self.cells if self.cells is not None else self.body
        if cells is not None:
            pts = []
            for x, y in cells:
                pts.append((x + self.moved_x, y + self.moved_y))
        else:
            pts = self.segments_now()
        return pts + self._carriers_now()

    def _way(self, force=False):
        """way_home from here, computed when first needed and again when the
        object has left the part of the field already searched."""
        if self.way is None or force:
            self.way_from = (self.moved_x, self.moved_y)
            goal = self._carriers_now() if self.by_carrier else self._points_now()
            self.way = way_home(self.world_size, self._footprint(), self._closed_now(), goal,
                                self.home_x, self.home_y, self.home_r2, (0, 0),
                                avoid=self._avoid())
        return self.way

    def _plan_on_way(self, tick):
        """The next step on way_home: downhill, best first (ties to the step
        that brings the nearest point closest to home); when every downhill
        step was blocked in turn, sideways steps join the rotation."""
        way = self._way()
        here = (self.moved_x - self.way_from[0], self.moved_y - self.way_from[1])
        if here not in way:
            way = self._way(True)
            here = (0, 0)
        if here not in way and self.bumps:
            # the blocked steps remembered cut every way home: some blocker
            # was a robot passing by; forget them and try again
            self.bumps = ()
            way = self._way(True)
            here = (0, 0)
        if here not in way:
            self._stop(tick, NO_PATH)
            return
        down = []
        side = []
        rel = _nearest(self._from_home())
        for ddx, ddy in STEPS:
            d = way.get((here[0] + ddx, here[1] + ddy))
            if d is None:
                continue
            item = ((d, self._home_d2(ddx, ddy, rel)), len(down) + len(side), ddx, ddy)
            if d < way[here]:
                down.append(item)
            elif d == way[here]:
                side.append(item)
        down.sort()
        side.sort()
        self._take(tick, down + side if self.blocked >= len(down) else down)

    def _plan_step(self, tick, h=None, plan=None):
        """h: `_held()`, when the caller has it; plan: `_closer_h` of its
        arrival points where they are now, when the caller has it (only
        the open arena's plan measures one, so it needs no check again)."""
        if plan is None and (self.closed is not None or self.lost_cells or self.bumps):
            self._plan_on_way(tick)
            return
        # Every step that brings the object's nearest segment closer to home,
        # best first; each blocked attempt moves on to the next candidate.
        # The arrival points stay in the object's frame, displaced per step
        # (`_nearest` kept nearly all of a handful of touches and cost more
        # than it saved).
        if h is None:
            h = self._held()
        if plan is None:
            plan = self._rank(h)
        ranked = plan[1]
        if ranked and self.world_size is not None and not self._inside(h[8], 1) \
                and self._walled(ranked):
            # against the arena's edge every step toward home would push the
            # object or a carrier off the arena, and retrying them would go on
            # forever (arrival "netlogo", seed 10): from now on plan round the
            # edge with way_home (no obstacles); runs never walled are unchanged
            self.closed = frozenset()
            self._plan_on_way(tick)
            return
        self._take(tick, ranked, h)

    def _inside(self, box, margin):
        """True if the box round `_footprint()` (`_held`'s, None: empty) is
        `margin` patches or more inside the arena -w..w: any step of at
        most `margin` each way then keeps it in."""
        if box is None:
            return True
        w = self.world_size - margin
        mx = self.moved_x
        my = self.moved_y
        return -w <= box[0] + mx and box[1] + mx <= w and -w <= box[2] + my \
            and box[3] + my <= w

    def _walled(self, ranked):
        """True if every step in `ranked` would put a cell of the object or a
        carrier outside the arena -w..w."""
        w = self.world_size
        box = self._box()
        if box is None:
            return not ranked
        x0, x1, y0, y1 = box
        for item in ranked:           # a step fits when the footprint's box does
            if -w <= x0 + item[2] and x1 + item[2] <= w and -w <= y0 + item[3] \
                    and y1 + item[3] <= w:
                return False
        return True

    def _box(self):
        """(x0, x1, y0, y1): the box round `_footprint()`, or None when it is empty."""
        box = self._held()[8]
        if box is None:
            return None
        x0, x1, y0, y1 = box
        mx = self.moved_x
        my = self.moved_y
        return x0 + mx, x1 + mx, y0 + my, y1 + my

    def _take(self, tick, ranked, h=None):
        """Command the candidate (key, order, dx, dy) the blocked count points
        at, the best first. h: `_held()`, when the caller has it."""
        if not ranked:
            # no step brings the object closer: it is as near home as it gets
            # (a touch reported at home); call it delivered rather than divide
            # by zero, which a journalled touch would repeat on every resume
            self.delivered_tick = tick
            return
        pick = ranked[self.blocked % len(ranked)]
        self.planned_from = (self.moved_x, self.moved_y)
        self.step = self.step % 255 + 1
        self.dx = pick[2]
        self.dy = pick[3]
        self._command(tick, h)

    def _command(self, tick, h=None):
        """h: `_held()`, when the caller has it."""
        self.step_sent_tick = tick
        # one fields tuple for every holder: a step commands about ten, and
        # a batch plans tens of thousands of steps
        f = (self.step, self.dx, self.dy)
        out = self.outbox
        kind = msg.TRANSPORT
        for node in (self._held() if h is None else h)[7]:
            out.append((node, kind, f))

    # -- liveness: holders that fall silent (lost_after > 0) ---------------------

    def _liveness(self, tick):
        """Drop every holder not heard for more than lost_after ticks (its
        power leaves the total, its cell becomes an obstacle, a new leader is
        chosen among the live holders) and take back a dropped one heard
        again. Runs in tick(), so the change is a decision, journalled with
        its snapshot (`lost`, `lost_cells`)."""
        lost = list(self.lost)
        cells = list(self.lost_cells)
        for t in self.touches:
            h = self.heard.get(t.node)
            if t.node in lost:
                if h is not None:            # heard again since it was dropped
                    k = lost.index(t.node)
                    del lost[k]
                    del cells[2 * k:2 * k + 2]
            elif h is None:
                # not heard since this host started (a resume): count from now
                self.heard[t.node] = (tick, self.moved_x, self.moved_y)
            elif tick - h[0] > self.lost_after:
                lost.append(t.node)
                cells += [t.rx + h[1], t.ry + h[2]]
                del self.heard[t.node]
        if tuple(lost) != self.lost:
            self.lost = tuple(lost)
            self.lost_cells = tuple(cells)
            self._relost()

    def _relost(self):
        """Power, leader and plan after `lost` changed."""
        power, leader = self._live()
        self.power = power
        if leader != self.leader:
            self.leader = leader
            lead = self.leader_touch()
            if lead is not None:
                # its pose now; its next HEARTBEAT says which step it has
                # done (0: none yet, never a step number)
                self.leader_x = lead.rx + self.moved_x
                self.leader_y = lead.ry + self.moved_y
                self.leader_done = 0
        self.way = None              # the obstacles changed

    def _live(self):
        """(power, leader) of the holders not lost: the leader is the first
        live one to have touched."""
        power = 0
        leader = 0
        for t in self.touches:
            if t.node not in self.lost:
                power += t.power
                if leader == 0:
                    leader = t.node
        return power, leader

    def replay(self, node, kind, f, tick):
        Recognising.replay(self, node, kind, f, tick)    # a RELEASE, else the roster's
        if self.waiting:
            # a journalled touch was judged at its tick's end, after every
            # report journalled before it: now, unjournalled and unACKed
            journal = self.journal
            self.journal = None
            self._touch_waiting(tick)
            self.journal = journal
            self.acks = {}
        # a journalled report says nothing of who is alive now: a resumed
        # host counts every holder's silence from its own first tick
        self.heard = {}

    def adopt(self, state):
        unknown = Roster.adopt(self, state)
        if "lost" in state:
            # the replayed reports rebuilt power and leader knowing nothing
            # of the lost holders: take them out again (the leader's pose is
            # in the snapshot)
            live = self._live()
            if live != (self.power, self.leader):
                self.power, self.leader = live
                self.way = None
        return unknown

    def _closed_now(self):
        """The cells the object may not enter: the map's and the lost holders'
        (a dead holder let go and stands still; under crowd "yield" the world
        pushes it aside like any bystander, so only the map's)."""
        if not self.lost_cells or self.crowd_yields:
            return self.closed
        out = set(self.closed or ())
        c = self.lost_cells
        for k in range(0, len(c), 2):
            out.add((c[k], c[k + 1]))
        return out

    def _bump(self):
        """The step planned from planned_from was blocked: remember the
        displacement it aimed at, so the plan (way_home from then on) goes
        round whatever stands there. A robot that stopped for good (dead,
        never heard of by the host when it was searching) blocks the same
        step forever, and the greedy rotation of the open arena can retry
        the same few blocked steps until the run stalls."""
        self.bumps = self.bumps + (self.planned_from[0] + self.dx,
                                   self.planned_from[1] + self.dy)
        self.blocked = 0
        self.way = None

    def _avoid(self):
        """The bumped displacements, relative to where the way is planned from."""
        out = []
        b = self.bumps
        for k in range(0, len(b), 2):
            out.append((b[k] - self.moved_x, b[k + 1] - self.moved_y))
        return out
