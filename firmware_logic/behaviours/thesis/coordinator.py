"""The host coordinator of the centralised phase, as pure logic.

It is fed decoded messages (node, kind, fields) by whatever link carries them
and returns the commands to send. It keeps the touch set, the power held
against the object's weight, the leader (first finder), plans the transport
toward home and detects arrival. Only robots that hold the object are
commanded (the thesis's flaw of 6.1.2, redirecting every robot, is fixed).

Time is the caller's tick counter; nothing here reads a clock.
"""

from firmware_logic import messages as msg

RESEND_AFTER = 4   # ticks without progress before a command is sent again
# host-side logic: portable, but allowed to allocate
SUBSET_SETUP = ("Touch", "Coordinator")
STEPS = ((-1, -1), (-1, 0), (0, -1), (1, -1), (-1, 1), (1, 0), (0, 1), (1, 1))


class Touch:
    def __init__(self, node, seq, rx, ry, sx, sy, power, tick):
        self.node = node
        self.seq = seq
        self.rx = rx
        self.ry = ry
        self.sx = sx
        self.sy = sy
        self.power = power
        self.tick = tick

    def as_tuple(self):
        return (self.node, self.seq, self.rx, self.ry, self.sx, self.sy,
                self.power, self.tick)


class Coordinator:
    def __init__(self, weight, home_x=-15, home_y=-15, home_radius=4, journal=None):
        """weight: the object's weight in hundredths (objectWeight * 100).

        journal: optional callable(touch) called for every newly accepted
        touch BEFORE it is acknowledged (the host process makes it durable).
        """
        self.weight = weight
        self.home_x = home_x
        self.home_y = home_y
        self.home_r2 = home_radius * home_radius
        self.journal = journal
        self.nodes = {}          # node -> (model, power)
        self.touches = []        # accepted, in order of acceptance
        self.seen = {}           # (node, seq) -> Touch
        self.power = 0
        self.leader = 0
        self.found_tick = -1
        self.converged_tick = -1
        self.delivered_tick = -1
        self.duplicates = 0
        self.rejected = {}       # reason -> count
        self.outbox = []
        # transport
        self.step = 0
        self.step_sent_tick = -1
        self.leader_x = 0        # leader pose, patches
        self.leader_y = 0
        self.leader_done = 0
        self.moved_x = 0         # object displacement since the touches
        self.moved_y = 0
        self.blocked = 0
        self.planned_from = (0, 0)
        self.dx = 0
        self.dy = 0
        self.halted = 0

    # -- input -------------------------------------------------------------

    def restore(self, touches):
        """Re-adopt touches recovered from a journal (no ACKs are sent)."""
        for t in touches:
            if (t.node, t.seq) not in self.seen:
                self._adopt(t)

    def on_message(self, node, kind, f, tick):
        if kind == msg.HELLO:
            self.nodes[node] = (f[0], f[1])
            self._send(node, msg.ACK, (0,))
        elif kind == msg.TOUCH:
            if node not in self.nodes:
                self._reject("touch from unannounced node")
                return
            key = (node, f[0])
            if key in self.seen:
                self.duplicates += 1
                self._send(node, msg.ACK, (f[0],))  # the first ACK may be lost
                return
            # stored in the object's frame: it may have moved since the start
            t = Touch(node, f[0], f[1] - self.moved_x, f[2] - self.moved_y,
                      f[3] - self.moved_x, f[4] - self.moved_y, f[5], tick)
            if self.journal is not None:
                self.journal(t)
            self._adopt(t)
            self._send(node, msg.ACK, (f[0],))
        elif kind == msg.HEARTBEAT:
            if node not in self.nodes:
                self._reject("heartbeat from unannounced node")
                return
            if node == self.leader and self.step > 0:
                self.leader_x = (f[1] + 128) >> 8
                self.leader_y = (f[2] + 128) >> 8
                self.leader_done = f[4]
                lead = self.leader_touch()
                self.moved_x = self.leader_x - lead.rx
                self.moved_y = self.leader_y - lead.ry
        else:
            self._reject("unexpected kind %d from a robot" % kind)

    def _adopt(self, t):
        self.seen[(t.node, t.seq)] = t
        self.touches.append(t)
        self.power += t.power
        if self.found_tick < 0 or t.tick < self.found_tick:
            self.found_tick = t.tick
        if self.leader == 0:
            self.leader = t.node
            self.leader_x = t.rx
            self.leader_y = t.ry

    def _reject(self, reason):
        self.rejected[reason] = self.rejected.get(reason, 0) + 1

    def _send(self, node, kind, fields):
        self.outbox.append((node, kind, fields))

    # -- the host's tick ---------------------------------------------------------

    def carriers(self):
        out = []
        for t in self.touches:
            if t.node not in out:
                out.append(t.node)
        return out

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
        if self.outbox:
            return False
        if self.delivered_tick >= 0:
            return self.halted == 1
        return self.converged_tick < 0 and not (self.touches and self.power >= self.weight)

    def tick(self, tick):
        """Advance the centralised phase; return and clear the commands to send."""
        if self.delivered_tick >= 0:
            if not self.halted:
                self.halted = 1
                self._send(msg.HOST, msg.HALT, (0,))
        elif self.converged_tick < 0:
            if self.touches and self.power >= self.weight:
                self.converged_tick = tick
                self._plan_step(tick)
        else:
            self._transport(tick)
        out = self.outbox
        self.outbox = []
        return out

    def _transport(self, tick):
        if self.leader_done == self.step:
            if self.moved_x == self.planned_from[0] and self.moved_y == self.planned_from[1]:
                self.blocked += 1
            else:
                self.blocked = 0
            if self._home_reached():
                self.delivered_tick = tick
                self.halted = 1
                self._send(msg.HOST, msg.HALT, (0,))
                return
            self._plan_step(tick)
        elif tick - self.step_sent_tick >= RESEND_AFTER:
            self._command(tick)

    def leader_touch(self):
        for t in self.touches:
            if t.node == self.leader:
                return t
        return None

    def _points_now(self):
        """Segments and carriers where they are now."""
        pts = self.segments_now()
        for t in self.touches:
            pts.append((t.rx + self.moved_x, t.ry + self.moved_y))
        return pts

    def _home_d2(self, ddx, ddy):
        best = -1
        for x, y in self.segments_now():
            d = (x + ddx - self.home_x) ** 2 + (y + ddy - self.home_y) ** 2
            if best < 0 or d < best:
                best = d
        return best

    def _home_reached(self):
        # the thesis stops transport when a robot is within 4 of home
        # (`wayHome < 4`); a segment that close counts as well
        for x, y in self._points_now():
            ddx = x - self.home_x
            ddy = y - self.home_y
            if ddx * ddx + ddy * ddy < self.home_r2:
                return True
        return False

    def _plan_step(self, tick):
        # Every step that brings the object's nearest segment closer to home,
        # best first; each blocked attempt moves on to the next candidate.
        here = self._home_d2(0, 0)
        ranked = []
        for ddx, ddy in STEPS:
            d = self._home_d2(ddx, ddy)
            if d < here:
                ranked.append((d, len(ranked), ddx, ddy))
        ranked.sort()
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
        self._command(tick)

    def _command(self, tick):
        self.step_sent_tick = tick
        for node in self.carriers():
            self._send(node, msg.TRANSPORT, (self.step, self.dx, self.dy))
