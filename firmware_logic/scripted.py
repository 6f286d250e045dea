"""A scripted robot body: every HAL answer comes from a seeded RNG.

ScriptHal implements every method of firmware_logic/hal.py without a world.
It is the fixture of the conformance run (bridge/firmware/conformance.py):
the same seeded script drives the FSM under CPython and under MicroPython
and both traces must be identical. It is written in the firmware subset
(docs/subset.md) so it runs unchanged on both and its per-call methods
allocate nothing: every sensing answer and every action is written as ints
into a trace buffer preallocated in __init__.

Answers are plausible, not physical:
    probe        NOTHING 32/40, ROBOT 3/40, WALL 2/40, CLAIMED 2/40, OBJECT 1/40
    field_ahead  0 mostly, 1..10 one time in 6
    field_here   0..10
    uphill       -1 one time in 4, else a multiple of 45
    holding      0 during the first half of the horizon (contested: another
                 robot wins every grip, so the FSM keeps searching and
                 resuming), then 1 seven times in 8
    recv         0 mostly; ACK(seq) 1..6 ticks after a TOUCH (a quarter of
                 the TOUCHes go unanswered, so retransmission runs); ACK(0)
                 some ticks after a HELLO; once a TOUCH was seen, TRANSPORT
                 one tick in 6 with increasing step numbers (a quarter of
                 them repeat the previous step); HALT at random in the last
                 tenth of the horizon, and at the latest two ticks before it;
                 each down message the behaviour declares (spec.MESSAGES
                 rows with direction DOWN, e.g. the thesis's RELEASE): once
                 at a random tick between a quarter of the horizon and the
                 HALT, and 1..3 ticks after half the reports (TOUCH or the
                 behaviour's own up messages) of the second half, DOWN_REACTS
                 times at most, so the FSM still goes on after it. Its
                 fields: a field named seq carries the robot's last report's
                 seq; a field in patches the robot's patch (x or y by the
                 field name's first letter) -4..+4; any other a random raw
                 value, each within the field's declared bounds.
Position is tracked from forward/carry in Q8 inside a 35 x 35 arena.

Ticks are counted by recv: the FSM calls recv until it answers 0 at the start
of every tick, so the first recv after a 0 begins the next tick. A driver may
call note_state(state) after each step to put the FSM state in the trace.
"""

from firmware_logic import fixedpoint as fx
from firmware_logic import messages as msg
from firmware_logic.hal import Hal
from firmware_logic.rng import Rng
from firmware_logic.hal import CLAIMED, NOTHING, OBJECT, ROBOT, WALL

# trace record: op, tick, then ARITY[op] ints
OP_X = 1
OP_Y = 2
OP_PROBE = 3
OP_FIELD_AHEAD = 4
OP_FIELD_HERE = 5
OP_UPHILL = 6
OP_HOLDING = 7
OP_FORWARD = 8
OP_CLAIM = 9
OP_CARRY = 10
OP_BEACON = 11
OP_SEND = 12
OP_RECV = 13
OP_STATE = 14

NAMES = ("", "x", "y", "probe", "field_ahead", "field_here", "uphill", "holding",
         "forward", "claim", "carry", "beacon", "send", "recv", "state")
ARITY = (0, 1, 1, 2, 2, 1, 1, 1, 2, 1, 2, 1, 7, 7, 1)
# how many of the record's ints are arguments; the rest are the answer
INPUTS = (0, 0, 0, 1, 1, 0, 0, 0, 2, 1, 2, 1, 7, 0, 1)
IS_ACTION = (0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 1, 0, 0)

ARENA = 35 * fx.ONE
SCRIPT_NODE = 0          # the script's RNG lane: node 0 is the host
# the down messages' own lane, so declaring one leaves the rest of the script alone
DOWN_LANE = 65520
DOWN_REACTS = 2          # deliveries of each down message in answer to reports
MAX_FIELDS = 6           # fields of one message (messages.check)

# how a down message's field is filled (ScriptHal.__init__ reads the row)
F_SEQ = 0                # the seq of the robot's last report
F_PX = 1                 # the robot's patch x, -4..+4
F_PY = 2                 # the robot's patch y, -4..+4
F_RANDOM = 3             # a random raw value

# lines() and drain_lines() build strings: not the step path
SUBSET_SETUP = ("ScriptHal.lines", "ScriptHal.drain_lines")


class ScriptHal(Hal):
    def __init__(self, seed, horizon=2000, capacity=1024, state_names=(), messages=()):
        """messages: the behaviour's own (its spec.MESSAGES); the script
        sends each one whose direction is DOWN."""
        self.state_names = state_names   # the behaviour's STATES, for the trace
        self.rng = Rng(seed, SCRIPT_NODE)
        self.drng = Rng(seed, DOWN_LANE)
        self.horizon = horizon
        self.contest_until = horizon // 2
        self.halt_from = horizon - horizon // 10
        self.buf = [0] * capacity
        self.cap = capacity
        self.n = 0
        self.dropped = 0           # records that did not fit
        self.actions = 0           # action records written (dropped included)
        self.records = 0
        self.tick = 0
        self.fresh = 1             # the next recv begins a tick
        self.px = fx.ONE * (2 + self.rng.below(31))
        self.py = fx.ONE * (2 + self.rng.below(31))
        # messages due this tick (flags), in CAN priority order
        self.q_halt = 0
        self.q_transport = 0
        self.q_ack = 0
        self.q_hello = 0
        # script state
        self.last_seq = 0          # seq of the robot's last report
        self.touched = 0
        self.halted = 0
        self.ack_due = 0
        self.ack_seq = 0
        self.hello_due = 0
        self.tstep = 0
        self.tdx = 0
        self.tdy = 0
        self.setup_messages(messages)

    def setup_messages(self, messages):
        """The behaviour's up kinds (its reports) and down messages, each down
        one with its schedule and, per field, how it is filled (kind, lo, hi)."""
        self.up_kinds = []
        self.down_kinds = []
        self.down_nfields = []
        self.down_at = []          # tick of the unprompted delivery
        self.down_due = []         # tick a delivery answering a report is due (0: none)
        self.down_left = []        # deliveries answering reports left
        self.down_q = []           # 1: delivered during this tick
        self.f_kind = []           # per down message MAX_FIELDS slots
        self.f_lo = []
        self.f_hi = []
        first = self.horizon // 4
        for m in messages:
            if m[2] == msg.UP:
                self.up_kinds.append(m[0])
                continue
            if m[2] != msg.DOWN:
                continue
            self.down_kinds.append(m[0])
            self.down_nfields.append(len(m[4]))
            self.down_at.append(first + self.drng.below(self.halt_from - first))
            self.down_due.append(0)
            self.down_left.append(DOWN_REACTS)
            self.down_q.append(0)
            j = 0
            while j < MAX_FIELDS:
                kind, lo, hi = F_RANDOM, 0, 0
                if j < len(m[4]):
                    name, size, signed, _div, unit, flo, fhi = m[4][j][:7]
                    bits = 8 * size
                    lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed \
                        else (0, (1 << bits) - 1)
                    if flo is not None:
                        lo = max(lo, flo)
                    if fhi is not None:
                        hi = min(hi, fhi)
                    if name == "seq":
                        kind = F_SEQ
                    elif unit == "patch":
                        kind = F_PY if name[:1] == "y" else F_PX
                self.f_kind.append(kind)
                self.f_lo.append(lo)
                self.f_hi.append(hi)
                j += 1

    # -- trace buffer ------------------------------------------------------

    def _open(self, op):
        """Start a record; return the index of its first argument or -1."""
        self.records += 1
        if IS_ACTION[op]:
            self.actions += 1
        n = self.n
        end = n + 2 + ARITY[op]
        if end > self.cap:
            self.dropped += 1
            return -1
        b = self.buf
        b[n] = op
        b[n + 1] = self.tick
        self.n = end
        return n + 2

    def _rec1(self, op, a):
        i = self._open(op)
        if i >= 0:
            self.buf[i] = a

    def _rec2(self, op, a, b):
        i = self._open(op)
        if i >= 0:
            buf = self.buf
            buf[i] = a
            buf[i + 1] = b

    def _rec7(self, op, a, b, c, d, e, f, g):
        i = self._open(op)
        if i >= 0:
            buf = self.buf
            buf[i] = a
            buf[i + 1] = b
            buf[i + 2] = c
            buf[i + 3] = d
            buf[i + 4] = e
            buf[i + 5] = f
            buf[i + 6] = g

    def clear(self):
        """Forget the recorded trace (the counters keep counting)."""
        self.n = 0

    def note_state(self, state):
        """Record the FSM state at the end of the current tick."""
        self._rec1(OP_STATE, state)

    # -- sensing -----------------------------------------------------------

    def x(self):
        self._rec1(OP_X, self.px)
        return self.px

    def y(self):
        self._rec1(OP_Y, self.py)
        return self.py

    def probe(self, heading):
        r = self.rng.below(40)
        if r == 0:
            r = OBJECT
        elif r < 4:
            r = ROBOT
        elif r < 6:
            r = WALL
        elif r < 8:
            r = CLAIMED
        else:
            r = NOTHING
        self._rec2(OP_PROBE, heading, r)
        return r

    def field_ahead(self, heading):
        r = 0
        if self.rng.below(6) == 0:
            r = 1 + self.rng.below(10)
        self._rec2(OP_FIELD_AHEAD, heading, r)
        return r

    def field_here(self):
        r = self.rng.below(11)
        self._rec1(OP_FIELD_HERE, r)
        return r

    def uphill(self):
        r = -1
        if self.rng.below(4) != 0:
            r = 45 * self.rng.below(8)
        self._rec1(OP_UPHILL, r)
        return r

    def holding(self):
        r = 0
        if self.tick >= self.contest_until and self.rng.below(8) != 0:
            r = 1
        self._rec1(OP_HOLDING, r)
        return r

    # -- acting ------------------------------------------------------------

    def _move_to(self, x, y):
        if x < 0:
            x = 0
        elif x > ARENA:
            x = ARENA
        if y < 0:
            y = 0
        elif y > ARENA:
            y = ARENA
        self.px = x
        self.py = y

    def forward(self, heading, step):
        self._rec2(OP_FORWARD, heading, step)
        self._move_to(self.px + fx.dx(heading, step), self.py + fx.dy(heading, step))

    def claim(self, heading):
        self._rec1(OP_CLAIM, heading)

    def carry(self, dx, dy):
        self._rec2(OP_CARRY, dx, dy)
        self._move_to(self.px + dx * fx.ONE, self.py + dy * fx.ONE)

    def beacon(self, on):
        self._rec1(OP_BEACON, on)

    # -- messages ------------------------------------------------------------

    def _is_report(self, kind):
        if kind == msg.TOUCH:
            return 1
        i = 0
        n = len(self.up_kinds)
        while i < n:
            if self.up_kinds[i] == kind:
                return 1
            i += 1
        return 0

    def send(self, kind, a0, a1, a2, a3, a4, a5):
        self._rec7(OP_SEND, kind, a0, a1, a2, a3, a4, a5)
        if self._is_report(kind):
            self.last_seq = a0
            # the behaviour's down messages answer some reports
            if self.tick >= self.contest_until:
                i = 0
                n = len(self.down_kinds)
                while i < n:
                    if self.down_left[i] and self.down_due[i] == 0 and self.drng.below(2) == 0:
                        self.down_left[i] -= 1
                        self.down_due[i] = self.tick + 1 + self.drng.below(3)
                    i += 1
        if kind == msg.TOUCH:
            self.touched = 1
            # a quarter of the reports go unanswered: the FSM retransmits
            if self.ack_due == 0 and self.rng.below(4) != 0:
                self.ack_due = self.tick + 1 + self.rng.below(6)
                self.ack_seq = a0
        elif kind == msg.HELLO:
            if self.hello_due == 0 and self.rng.below(3) == 0:
                self.hello_due = self.tick + 1 + self.rng.below(4)

    def _plan_tick(self):
        """Decide which messages arrive during the tick that begins now."""
        t = self.tick
        if self.ack_due and t >= self.ack_due:
            self.ack_due = 0
            self.q_ack = 1
        if self.hello_due and t >= self.hello_due:
            self.hello_due = 0
            self.q_hello = 1
        if self.touched and not self.halted and self.rng.below(6) == 0:
            if self.tstep > 0 and self.rng.below(4) == 0:
                self.q_transport = 1          # a repeat of the last step
            else:
                self.tstep = self.tstep % 255 + 1
                self.tdx = self.rng.below(3) - 1
                self.tdy = self.rng.below(3) - 1
                self.q_transport = 1
        i = 0
        n = len(self.down_kinds)
        while i < n:
            if self.down_due[i] and t >= self.down_due[i]:
                self.down_due[i] = 0
                self.down_q[i] = 1
            if t == self.down_at[i]:
                self.down_q[i] = 1
            i += 1
        if not self.halted and t >= self.halt_from:
            if self.rng.below(16) == 0 or t >= self.horizon - 2:
                self.halted = 1
                self.q_halt = 1

    def _deliver(self, buf, kind, a0, a1, a2):
        buf[0] = a0
        buf[1] = a1
        buf[2] = a2
        buf[3] = 0
        buf[4] = 0
        buf[5] = 0
        self._rec7(OP_RECV, kind, a0, a1, a2, 0, 0, 0)
        return kind

    def recv(self, buf):
        if self.fresh:
            self.fresh = 0
            self.tick += 1
            self._plan_tick()
        if self.q_halt:
            self.q_halt = 0
            return self._deliver(buf, msg.HALT, 0, 0, 0)
        if self.q_transport:
            self.q_transport = 0
            return self._deliver(buf, msg.TRANSPORT, self.tstep, self.tdx, self.tdy)
        if self.q_ack:
            self.q_ack = 0
            return self._deliver(buf, msg.ACK, self.ack_seq, 0, 0)
        if self.q_hello:
            self.q_hello = 0
            return self._deliver(buf, msg.ACK, 0, 0, 0)
        i = 0
        n = len(self.down_kinds)
        while i < n:
            if self.down_q[i]:
                self.down_q[i] = 0
                return self._deliver_down(buf, i)
            i += 1
        self.fresh = 1
        self._rec7(OP_RECV, 0, 0, 0, 0, 0, 0, 0)
        return 0

    def _field(self, k):
        """The value of field slot k (setup_messages) for a delivery now."""
        kind = self.f_kind[k]
        if kind == F_SEQ:
            v = self.last_seq
        elif kind == F_PX:
            v = fx.patch(self.px) + self.drng.below(9) - 4
        elif kind == F_PY:
            v = fx.patch(self.py) + self.drng.below(9) - 4
        else:
            v = self.f_lo[k] + self.drng.below(self.f_hi[k] - self.f_lo[k] + 1)
        if v < self.f_lo[k]:
            v = self.f_lo[k]
        elif v > self.f_hi[k]:
            v = self.f_hi[k]
        return v

    def _deliver_down(self, buf, i):
        base = i * MAX_FIELDS
        nf = self.down_nfields[i]
        j = 0
        while j < MAX_FIELDS:
            buf[j] = self._field(base + j) if j < nf else 0
            j += 1
        kind = self.down_kinds[i]
        self._rec7(OP_RECV, kind, buf[0], buf[1], buf[2], buf[3], buf[4], buf[5])
        return kind

    # -- dumping (allocates: never call it from a step) ------------------------

    def lines(self):
        """The recorded trace as text lines: `tick name args [-> answer]`."""
        out = []
        b = self.buf
        i = 0
        while i < self.n:
            op = b[i]
            k = ARITY[op]
            ins = INPUTS[op]
            parts = [str(b[i + 1]), NAMES[op]]
            j = 0
            while j < k:
                if j == ins:
                    parts.append("->")
                v = b[i + 2 + j]
                if op == OP_STATE:
                    parts.append(self.state_names[v] if v < len(self.state_names)
                                 else str(v))
                else:
                    parts.append(str(v))
                if op == OP_RECV and j == 0 and v == 0:
                    break
                j += 1
            out.append(" ".join(parts))
            i += 2 + k
        return out

    def drain_lines(self):
        """lines(), then clear()."""
        out = self.lines()
        self.n = 0
        return out
