"""Aggregation FSM: same HAL and messages as the thesis, another behaviour.

One `step(hal)` is one tick; all sensing happens before the tick's single
movement request, as docs/tick-semantics.md requires; nothing allocates.
"""

from firmware_logic import fixedpoint as fx
from firmware_logic import messages as msg
from .spec import CLIMB, HALT, LEAVE, SEARCH, STAY, WALK
from firmware_logic.hal import NOTHING, ROBOT
from firmware_logic.rng import Rng

RESEND = 8           # ticks between two reports of the stop until it is ACKed
RECHECK = 32         # a stopped robot looks again this often; alone, it leaves
HEARTBEAT_EVERY = 64


class Robot:
    def __init__(self, node, seed, model, vision_span, field_defiance, power):
        self.node = node
        self.model = model
        self.span = vision_span
        self.defiance = field_defiance
        self.power = power
        self.rng = Rng(seed, node)
        self.heading = self.rng.below(360)
        self.state = SEARCH
        self.phase = 0
        self.ticks = 0
        self.hello_acked = 0
        self.seq = 0          # number of the current stop report (1..255)
        self.reported = 0     # 1 once the host ACKed the stop report
        self.rx = 0
        self.ry = 0
        self.sx = 0
        self.sy = 0
        self.rxbuf = [0, 0, 0, 0, 0, 0]

    def step(self, hal):
        self.ticks += 1
        k = hal.recv(self.rxbuf)
        while k:
            if k == msg.ACK:
                if self.rxbuf[0] == 0:
                    self.hello_acked = 1
                elif self.state == STAY and self.rxbuf[0] == self.seq:
                    self.reported = 1
            elif k == msg.HALT and self.state != HALT:
                self.state = HALT
                hal.beacon(0)
            k = hal.recv(self.rxbuf)
        s = self.state
        if s == SEARCH or s == CLIMB:
            self._move(hal)
        elif s == STAY and (self.ticks % RECHECK) == 0 and hal.probe(self.heading) != ROBOT:
            # the robot it touched has walked away: leave, and say so at once
            self.state = SEARCH
            hal.beacon(0)
            hal.send(LEAVE, self.seq, hal.x(), hal.y(), 0, 0, 0)
        self._housekeeping(hal)

    def _move(self, hal):
        if hal.probe(self.heading) == ROBOT:
            self._stop(hal)
            return
        if hal.field_here() > 0:
            self.state = CLIMB
            if self.phase == 0:
                u = hal.uphill()
                if u >= 0:
                    self.heading = u
                self._ahead(hal)
                if self.defiance > 0:
                    self.phase = 1
                return
            self.phase += 1
            if self.phase > self.defiance:
                self.phase = 0
        else:
            self.state = SEARCH
            self.phase = 0
        self._wander(hal)

    def _wander(self, hal):
        if self.model == WALK:
            self.heading = self.rng.below(360)
        elif self.rng.below(2) == 0:
            self.heading = (self.heading + self.rng.below(self.span + 1)) % 360
        else:
            self.heading = (self.heading - self.rng.below(self.span + 1)) % 360
        self._ahead(hal)

    def _ahead(self, hal):
        if hal.probe(self.heading) != NOTHING:
            self.heading = self.rng.below(360)
            return
        hal.forward(self.heading, fx.ONE)

    def _stop(self, hal):
        self.state = STAY
        self.seq = self.seq % 255 + 1
        self.reported = 0
        hal.beacon(1)
        x = hal.x()
        y = hal.y()
        self.rx = fx.patch(x)
        self.ry = fx.patch(y)
        self.sx = fx.patch(x + fx.dx(self.heading, fx.ONE))
        self.sy = fx.patch(y + fx.dy(self.heading, fx.ONE))
        self._report(hal)

    def _report(self, hal):
        hal.send(msg.TOUCH, self.seq, self.rx, self.ry, self.sx, self.sy, self.power)

    def _housekeeping(self, hal):
        if not self.hello_acked and (self.ticks % 4) == 1:
            hal.send(msg.HELLO, self.model, self.power, msg.FIRMWARE_VERSION, 0, 0, 0)
        if self.state == STAY and not self.reported and (self.ticks % RESEND) == 0:
            self._report(hal)
        if (self.ticks % HEARTBEAT_EVERY) == 0:
            hal.send(msg.HEARTBEAT, self.state, hal.x(), hal.y(), self.heading, 0, 0)
