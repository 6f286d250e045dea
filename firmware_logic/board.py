"""The MicroPython robot's runtime: a tethered body and the main loop.

The board talks to the host over one serial link (COBS + CRC frames,
firmware_logic/framing.py) carrying the message schema of
firmware_logic/messages.py, the same as on CAN. Besides the robot's own
messages (HELLO, TOUCH, HEARTBEAT up; ACK, TRANSPORT, HALT down) the link
carries the body: `TetherHal` answers the FSM's sensing calls by asking the
host with SENSOR frames and reports actions with ACTION frames, and a body
server on the host side (sim_backend/emulators/tether.py: the sim world; or
a real robot's driver) answers them. A board with its own sensors subclasses
TetherHal and overrides the sensing and acting methods with pin reads.

Body protocol (node = this robot; all requests are retried until answered):

    SENSOR(tick, index, query, arg, 0)  ->  SENSOR(tick, index, query, arg, value)
    ACTION(tick, index, action, a, b)   ->  (no reply; the intent of this tick)
    ACTION(tick, index, END, 0, 0)      ->  ACTION(tick, index, END, 0, 0) once the
                                            world has applied the tick
    ACTION(tick, index, STOP, 0, 0)     ->  (no reply; the loop has ended, nothing
                                            more comes from this run)

`tick` is the robot's tick modulo 65536 and `index` a per-request counter
modulo 256, so a late or repeated answer is recognised and ignored.

The port is whatever the board offers, passed in by the board's main.py:
an object with `read(timeout_ms)` -> a byte or -1 on timeout,
`write(buf, n)`, and `ms()` -> a millisecond counter that wraps at a
multiple of 2**30 (MicroPython's `time.ticks_ms()`), which gives a
request's answer a deadline (see firmware_logic/board_main.py).
"""

from firmware_logic import framing
from firmware_logic import messages as msg
from firmware_logic import hal
from firmware_logic.hal import Hal
from firmware_logic.hal import WALL

# SENSOR queries and ACTION codes: the HAL's (firmware_logic/hal.py); END
# closes a tick's actions on the tether; STOP is the board's last frame of a
# run (its loop has ended), so a host knows when the port is free again
A_END = 0
A_STOP = 255


def is_stop(kind, fields):
    """Whether a board's frame (kind, fields) is its STOP: ACTION's fields
    are (tick, index, code, a, b)."""
    return kind == msg.ACTION and fields[2] == A_STOP


INBOX = 8          # queued host messages between two FSM steps
REPLY_MS = 200     # wait for one answer before asking again
MS_MASK = 0x3FFFFFFF   # port.ms() wraps at a multiple of 2**30 (ticks_ms)
RETRIES = 25       # then give up on this answer (link down for ~5 s)


class TetherHal(Hal):
    def __init__(self, port, node):
        self.port = port
        self.node = node
        self.enc = framing.Encoder()
        self.dec = framing.Decoder()
        self.tick = 0
        self.index = 0
        self.reply_ms = REPLY_MS
        self.retries = RETRIES
        self.lost = 0              # answers given up on
        self.resent = 0            # requests sent again
        self.ignored = 0           # frames for other nodes or late answers
        # inbox: a ring of (kind, 6 fields) rows, preallocated
        self.box = bytearray(INBOX)
        self.boxf = []
        i = 0
        while i < INBOX:
            self.boxf.append([0, 0, 0, 0, 0, 0])
            i += 1
        self.head = 0
        self.count = 0
        self.overflow = 0
        self.value = 0
        self.halted = 0
        self.robot = None

    # -- link -----------------------------------------------------------------

    def _write(self, kind, a0, a1, a2, a3, a4, a5):
        n = self.enc.frame(kind, self.node, a0, a1, a2, a3, a4, a5)
        self.port.write(self.enc.out, n)

    def _keep(self):
        """Queue the frame just decoded for the FSM (ACK, TRANSPORT, HALT)."""
        d = self.dec
        if d.kind == msg.HALT:
            self.halted = 1
        if self.count >= INBOX:
            self.overflow += 1
            return
        k = (self.head + self.count) % INBOX
        self.box[k] = d.kind
        row = self.boxf[k]
        i = 0
        while i < d.nfields:
            row[i] = d.fields[i]
            i += 1
        self.count += 1

    def _pump(self, timeout_ms, kind, index, code):
        """Read frames until the answer (kind, tick, index, code) arrives
        (return 1, its value in self.value) or timeout_ms have passed on the
        port's clock (return 0: ask again). A deadline, not a silence: other
        traffic (HALT, ACK, noise) never holds a request back from its resend."""
        d = self.dec
        port = self.port
        start = port.ms()
        left = timeout_ms
        while True:
            b = port.read(left)
            if b < 0:
                return 0
            left = timeout_ms - ((port.ms() - start) & MS_MASK)
            if not d.feed(b):
                if left <= 0:
                    return 0
                continue
            if d.node != self.node and d.node != msg.HOST:
                self.ignored += 1
            else:
                k = d.kind
                if k == msg.SENSOR or k == msg.ACTION:
                    f = d.fields
                    if (k == kind and f[0] == (self.tick & 0xFFFF) and f[1] == index
                            and f[2] == code):
                        self.value = f[4]
                        return 1
                    self.ignored += 1
                else:
                    self._keep()
            if left <= 0:
                return 0

    def _ask(self, query, arg, default):
        self.index = (self.index + 1) & 0xFF
        t = self.tick & 0xFFFF
        tries = 0
        while tries < self.retries:
            if tries:
                self.resent += 1
            self._write(msg.SENSOR, t, self.index, query, arg, 0, 0)
            if self._pump(self.reply_ms, msg.SENSOR, self.index, query):
                return self.value
            tries += 1
        self.lost += 1
        return default

    def _act(self, action, a, b):
        self.index = (self.index + 1) & 0xFF
        self._write(msg.ACTION, self.tick & 0xFFFF, self.index, action, a, b, 0)

    def end_tick(self):
        """Tell the body server this tick is decided; wait until it is applied.
        Returns 1 when applied, 0 when the server never answered."""
        self.index = (self.index + 1) & 0xFF
        t = self.tick & 0xFFFF
        ok = 0
        tries = 0
        while tries < self.retries:
            if tries:
                self.resent += 1
            self._write(msg.ACTION, t, self.index, A_END, 0, 0, 0)
            if self._pump(self.reply_ms, msg.ACTION, self.index, A_END):
                ok = 1
                break
            tries += 1
        if not ok:
            self.lost += 1
        self.tick += 1
        return ok

    def stop(self):
        """The last frame of a run: the loop has ended and this board reads
        nothing more. Sent after the loop, never answered; a host waits for
        it (not for silence) before it takes the port for something else,
        e.g. the REPL (a board still in its loop would swallow the REPL's
        Ctrl-C / Ctrl-A as link bytes)."""
        self.index = (self.index + 1) & 0xFF
        self._write(msg.ACTION, self.tick & 0xFFFF, self.index, A_STOP, 0, 0, 0)

    # -- sensing ---------------------------------------------------------------

    def x(self):
        return self._ask(hal.POS_X, 0, 0)

    def y(self):
        return self._ask(hal.POS_Y, 0, 0)

    def probe(self, heading):
        # no answer: behave as if a wall were ahead (never move blind)
        return self._ask(hal.PROBE, heading, WALL)

    def field_ahead(self, heading):
        return self._ask(hal.FIELD_AHEAD, heading, 0)

    def field_here(self):
        return self._ask(hal.FIELD_HERE, 0, 0)

    def uphill(self):
        return self._ask(hal.UPHILL, 0, -1)

    def holding(self):
        return self._ask(hal.HOLDING, 0, 0)

    # -- acting ---------------------------------------------------------------------

    def forward(self, heading, step):
        self._act(hal.FORWARD, heading, step)

    def claim(self, heading):
        self._act(hal.CLAIM, heading, 0)

    def carry(self, dx, dy):
        self._act(hal.CARRY, dx, dy)

    def beacon(self, on):
        self._act(hal.BEACON, on, 0)

    # -- messages --------------------------------------------------------------------

    def send(self, kind, a0, a1, a2, a3, a4, a5):
        self._write(kind, a0, a1, a2, a3, a4, a5)

    def recv(self, buf):
        if self.count == 0:
            # nothing queued: take what has already arrived, without waiting
            d = self.dec
            b = self.port.read(0)
            while b >= 0:
                if d.feed(b):
                    if d.node == self.node or d.node == msg.HOST:
                        k = d.kind
                        if k != msg.SENSOR and k != msg.ACTION:
                            self._keep()
                b = self.port.read(0)
            if self.count == 0:
                return 0
        k = self.head
        row = self.boxf[k]
        i = 0
        while i < 6:
            buf[i] = row[i]
            i += 1
        self.head = (k + 1) % INBOX
        self.count -= 1
        return self.box[k]


def run(port, node, robot, spec, max_ticks, linger, guard=None):
    """The robot's main loop: step the FSM, let the body apply the tick,
    until `max_ticks` ticks (0: forever) or `linger` ticks after the
    behaviour's "halt" state; then one ACTION STOP frame says the loop has
    ended. Returns the HAL (its counters), with the robot as `hal.robot`.
    robot: the behaviour's FSM, built from its robot_args (main.py builds it
    from robot_config.ARGS, firmware_logic/board_main.py); spec: its spec.py
    (its own message kinds are put in use here, its STATES name "halt").
    guard: a heap check (firmware_logic/board_main.py HeapGuard): after
    guard.warmup ticks, guard.tick(robot, hal) runs each whole tick under
    heap_lock() and counts the ticks that tried to allocate."""
    if hasattr(spec, "MESSAGES"):
        msg.activate(spec.MESSAGES)
    halt = spec.STATES.index("halt")
    hal = TetherHal(port, node)
    hal.robot = robot
    after = 0
    while max_ticks == 0 or hal.tick < max_ticks:
        if guard is not None and hal.tick >= guard.warmup:
            guard.tick(robot, hal)
        else:
            robot.step(hal)
            hal.end_tick()
        if robot.state == halt:
            after += 1
            if after > linger:
                break
    hal.stop()
    return hal
