"""The robot behaviour of the thesis (Appendix A) as a finite-state machine.

One call to `Robot.step(hal)` is one control tick. The robot senses and acts
only through `hal` (see firmware_logic/hal.py), owns its heading, its RNG and
its report bookkeeping, and never allocates in the step path, so it runs
unchanged on CPython and on a MicroPython board.

Tick rule (docs/tick-semantics.md): every sensing call of a tick happens
before the tick's single movement request (`forward`, `claim` or `carry`),
so a world can answer all robots from the state at the start of the tick.
The thesis's go-loop order (RandomHead, FindObject, FindField) becomes
FindObject, FindField/FollowField, RandomHead within one tick; over ticks the
sequence of decisions is the thesis's.
"""

from firmware_logic import fixedpoint as fx
from firmware_logic import messages as msg
from firmware_logic.rng import Rng

from firmware_logic.hal import (BEACON_LEADER, BEACON_ON, CLAIMED, NOTHING,  # noqa: F401
                               OBJECT, ROBOT, WALL)

# the behaviour's own modules by relative import: the package works under any
# name (firmware_logic.behaviours.thesis here, `behaviour` on a board)
from .spec import (ANT, CARRY, FIELD, FIREFLY, FROG, GRASP, HALT, HOLD,  # noqa: F401
                   LEVY, MOTH, RELEASE, RELEASE_TICKS, SEARCH, STATES)

STATE_NAMES = STATES

# report retransmission, in ticks: first retry after RETX_FIRST, doubling
RETX_FIRST = 4
RETX_MAX = 64
HEARTBEAT_EVERY = 64
# Levy flights: a flight is 2**k + random(2**k) steps, k >= 1 with probability
# levy_q / 1000, k >= 2 with (levy_q / 1000)**2, ...; k stops at LEVY_KMAX
# (63 steps: longer than the 37-patch arena is crossed anyway)
LEVY_KMAX = 5
# moth: degrees it turns each step where the field peaks (circling the light)
MOTH_SPIRAL = 45


class Robot:
    def __init__(self, node, seed, model, vision_span, field_defiance, power, leader_field=0,
                 ant_turn=0, levy_q=500, moth_noise=30, frog_pause=4, frog_jump=4,
                 move_first=0):
        self.node = node
        # 1: a leader (found the object from outside any field) lights its
        # beacon as BEACON_LEADER, and the world pins its patch's field to 10
        # every tick (Appendix A go's `set field 10`; scenario leaderField)
        self.leader_field = leader_field
        self.model = model
        self.span = vision_span
        self.defiance = field_defiance
        self.power = power            # hundredths of a unit (rPower * 100)
        self.step_len = fx.QUARTER if model == ANT else fx.ONE
        # 1: an ant blocked on its step turns within its span (thesis 6.1.1's
        # redesign, scenario antBlocked = "turn"); 0: a random heading (Appendix A)
        self.ant_turn = ant_turn
        self.levy_q = levy_q          # per mille: levyMu's chance of doubling a flight
        self.moth_noise = moth_noise  # degrees either side of the moth's uphill heading
        self.frog_pause = frog_pause  # ticks a frog sits between jumps
        self.frog_jump = frog_jump    # steps of one jump
        # 1: the first tick is go's RandomHead alone, so the search runs
        # RandomHead, FindObject, FindField from the start as Appendix A's go
        # (scenario firstMove "netlogo"); 0: it starts with FindObject
        self.move_first = move_first
        self.flight = 0               # Levy: steps left of the flight; frog: of the jump
        self.pause = 0                # frog: ticks left sitting
        self.rng = Rng(seed, node)
        self.heading = self.rng.below(360)
        self.state = SEARCH
        self.resume = SEARCH          # where to go back to if a grasp fails
        self.phase = 0                # position in the in-field cycle
        self.first = 0                # touched the object from outside any field
        self.claim_heading = 0
        self.ticks = 0
        # touch report and its retransmission
        self.seq = 0
        self.pending = 0
        self.retx_timer = 0
        self.retx_every = RETX_FIRST
        self.rx = 0
        self.ry = 0
        self.sx = 0
        self.sy = 0
        self.hello_acked = 0
        # centralised phase
        self.last_step = 0            # last transport step received
        self.done_step = 0            # last transport step executed
        self.cdx = 0
        self.cdy = 0
        self.carry_due = 0
        # RELEASE (the host recognised a decoy): walk off the segment on the next
        # tick, then claim nothing in the box ax0..ax1, ay0..ay1 for
        # avoid_ticks ticks
        self.leave = 0
        self.avoid_ticks = 0
        self.ax0 = 0
        self.ay0 = 0
        self.ax1 = 0
        self.ay1 = 0
        self.rxbuf = [0, 0, 0, 0, 0, 0]

    # -- the tick ---------------------------------------------------------

    def step(self, hal):
        self.ticks += 1
        if self.avoid_ticks > 0:
            self.avoid_ticks -= 1     # the tick of the RELEASE counts as its first
        k = hal.recv(self.rxbuf)
        while k:
            self._on_message(hal, k)
            k = hal.recv(self.rxbuf)
        if self.leave:
            # let go: one step straight off the segment (a forward intent
            # frees the grip, kernel.let_go); the search resumes next tick
            self.leave = 0
            hal.forward((self.claim_heading + 180) % 360, self.step_len)
            self._housekeeping(hal)
            return
        s = self.state
        if s == SEARCH:
            self._search(hal)
        elif s == FIELD:
            self._field(hal)
        elif s == GRASP:
            self._grasp(hal)
        elif s == CARRY:
            self._carry(hal)
        self._housekeeping(hal)

    def _search(self, hal):
        # FindObject, then FindField, then RandomHead (one move at most)
        if self.move_first and self.ticks == 1:
            self._random_head(hal)
            return
        if self._find_object(hal):
            return
        if hal.field_ahead(self.heading) > 0:
            self.state = FIELD
            self._follow_field(hal)
            self.phase = 1 if self.defiance > 0 else 0
            return
        self._random_head(hal)

    def _field(self, hal):
        # cycle: [FindObject + FollowField], then fieldDefiance x RandomHead
        if self.phase == 0:
            if self._find_object(hal):
                return
            self._follow_field(hal)
            if self.defiance > 0:
                self.phase = 1
            return
        self._random_head(hal)
        self.phase += 1
        if self.phase > self.defiance:
            self.phase = 0

    def _grasp(self, hal):
        if not hal.holding():
            # another robot took the segment in the same tick
            self.state = self.resume
            self.phase = 0
            return
        self.state = HOLD
        if self.leader_field and self.first:
            hal.beacon(BEACON_LEADER)
        else:
            hal.beacon(BEACON_ON)
        x = hal.x()
        y = hal.y()
        self.rx = fx.patch(x)
        self.ry = fx.patch(y)
        self.sx = fx.patch(x + fx.dx(self.claim_heading, fx.ONE))
        self.sy = fx.patch(y + fx.dy(self.claim_heading, fx.ONE))
        self.seq += 1
        if self.seq > 255:
            self.seq = 1
        self.pending = 1
        self.retx_every = RETX_FIRST
        self._send_touch(hal)

    def _carry(self, hal):
        # Report the pose first: it reflects every step executed in earlier
        # ticks, which is what `done_step` says, so the host never plans
        # from a pose that is about to change.
        hal.send(msg.HEARTBEAT, CARRY, hal.x(), hal.y(), self.heading,
                 self.done_step, 0)
        if self.carry_due:
            self.carry_due = 0
            hal.carry(self.cdx, self.cdy)
            self.done_step = self.last_step

    # -- thesis procedures -------------------------------------------------

    def _find_object(self, hal):
        m = self.model
        if m == FIREFLY:
            h = 0
            while h < 360:
                if self._look_for_object(hal, h):
                    return 1
                self.heading = self.rng.below(360)
                h += 90
            return 0
        if m == FROG and self.flight <= 0:
            # sitting: looks round, the four quarters from its heading
            h = 0
            while h < 360:
                if self._look_for_object(hal, (self.heading + h) % 360):
                    return 1
                h += 90
            return 0
        if m == ANT or m == MOTH:
            self._turn()
        # Levy and a jumping frog look along their flight
        return self._look_for_object(hal, self.heading)

    def _look_for_object(self, hal, h):
        if hal.probe(h) != OBJECT:
            return 0
        if self.avoid_ticks > 0 and self._avoided(hal, h):
            return 0
        hal.claim(h)
        self.heading = h
        self.claim_heading = h
        self.resume = self.state
        # go's `not foundField`: judged at this touch (a failed grasp from
        # SEARCH and a later touch from FIELD make no leader)
        self.first = 1 if self.state == SEARCH else 0
        self.state = GRASP
        return 1

    def _avoided(self, hal, h):
        # the segment ahead lies in the box of a released decoy
        px = fx.patch(hal.x() + fx.dx(h, fx.ONE))
        py = fx.patch(hal.y() + fx.dy(h, fx.ONE))
        return self.ax0 <= px <= self.ax1 and self.ay0 <= py <= self.ay1

    def _turn(self):
        if self.rng.below(100) % 2 == 0:
            self.heading = (self.heading + self.rng.below(self.span)) % 360
        else:
            self.heading = (self.heading - self.rng.below(self.span)) % 360

    def _random_head(self, hal):
        m = self.model
        if m == FIREFLY:
            self.heading = self.rng.below(360)
        elif m == LEVY:
            if self.flight <= 0:
                self._new_flight()
            self.flight -= 1
        elif m == FROG:
            if self.flight <= 0:
                # sitting; when the pause is over, jump: frogJump forward steps
                self.pause -= 1
                if self.pause > 0:
                    return
                self.heading = self.rng.below(360)
                self.flight = self.frog_jump
            self.flight -= 1
            if self.flight <= 0:
                self.pause = self.frog_pause
        elif m == MOTH and self.state == FIELD:
            self._moth_steer(hal)
        self._head_carefully(hal)

    def _new_flight(self):
        # a truncated discrete power law (docs/movement-models.md): P(flight
        # >= 2**k) = q**k, so P(length > L) ~ L**-(mu - 1) for q = 2**(1 - mu)
        k = 0
        while k < LEVY_KMAX and self.rng.below(1000) < self.levy_q:
            k += 1
        self.flight = (1 << k) + self.rng.below(1 << k)
        self.heading = self.rng.below(360)

    def _moth_steer(self, hal):
        # toward the strongest reading with noise; where the field peaks
        # (no neighbour stronger), circle round the light
        u = hal.uphill()
        if u >= 0:
            n = self.moth_noise
            self.heading = (u + self.rng.below(2 * n + 1) - n + 360) % 360
        else:
            self.heading = (self.heading + MOTH_SPIRAL) % 360

    def _head_carefully(self, hal):
        if hal.probe(self.heading) != NOTHING:
            m = self.model
            if m == ANT and self.ant_turn:
                self._turn()
            else:
                self.heading = self.rng.below(360)
            if m == LEVY or m == FROG:
                # the flight or jump ends at an obstacle (a frog sits again)
                self.flight = 0
                self.pause = self.frog_pause
            return
        hal.forward(self.heading, self.step_len)

    def _follow_field(self, hal):
        if self.model == MOTH:
            self._moth_steer(hal)
            self._head_carefully(hal)
            return
        u = hal.uphill()
        if u >= 0:
            self.heading = u
        self._head_carefully(hal)

    # -- messages ------------------------------------------------------------

    def _on_message(self, hal, kind):
        b = self.rxbuf
        if kind == msg.ACK:
            # any ACK acknowledges the HELLO too: the host accepts a touch only
            # from an announced node, and sends one ACK per node per tick
            self.hello_acked = 1
            if self.pending and b[0] == self.seq:
                self.pending = 0
        elif kind == msg.TRANSPORT:
            # The host commands only carriers whose touch it journalled, and
            # ACKs the touch before its first TRANSPORT; one before that ACK
            # cannot come from the host (or comes before convergence) and is
            # ignored. A lost ACK costs a resend: the host repeats both.
            if (self.state == HOLD or self.state == CARRY) and not self.pending:
                if b[0] != self.last_step:
                    self.state = CARRY
                    self.last_step = b[0]
                    self.cdx = b[1]
                    self.cdy = b[2]
                    self.carry_due = 1
        elif kind == msg.HALT:
            if self.state != HALT:
                self.state = HALT
                hal.beacon(0)
        elif kind == RELEASE:
            # the host recognised the held object as a decoy: beacon off,
            # let go (next tick), search on and leave that object alone for
            # a while; a RELEASE in any other state is stale and ignored
            if self.state == HOLD:
                hal.beacon(0)
                self.state = SEARCH
                self.phase = 0
                self.pending = 0
                self.first = 0
                self.leave = 1
                self.ax0 = b[0]
                self.ay0 = b[1]
                self.ax1 = b[2]
                self.ay1 = b[3]
                self.avoid_ticks = RELEASE_TICKS

    def _send_touch(self, hal):
        hal.send(msg.TOUCH, self.seq, self.rx, self.ry, self.sx, self.sy, self.power)
        self.retx_timer = self.retx_every

    def _housekeeping(self, hal):
        if not self.hello_acked and (self.ticks % RETX_FIRST) == 1:
            hal.send(msg.HELLO, self.model, self.power, msg.FIRMWARE_VERSION, 0, 0, 0)
        if self.pending:
            # due, then count down: the tick of a send (the first one in
            # _grasp, earlier this tick) counts as its first tick, so the first
            # retry goes RETX_FIRST ticks after the send, the next 2 x later
            if self.retx_timer <= 0:
                self.retx_every = self.retx_every * 2
                if self.retx_every > RETX_MAX:
                    self.retx_every = RETX_MAX
                self._send_touch(hal)
            self.retx_timer -= 1
        if self.state != CARRY and (self.ticks % HEARTBEAT_EVERY) == 0:
            hal.send(msg.HEARTBEAT, self.state, hal.x(), hal.y(), self.heading,
                     self.done_step, 0)
