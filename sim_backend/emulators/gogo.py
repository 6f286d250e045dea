"""A serial-generation GoGo Board on a pty, on a differential-drive robot in the sim world.

Written from the protocol description (../shared/design/protocols.md,
docs/serial.md) on its own: it shares no code with bridge/serial/gogo.py,
so a bug in one shows up against the other.

Serial: 9600 baud 8N1 (10 bits a byte on the wire). Every byte the host
sends is echoed, one byte time after it arrived; a complete command
(`0x54 0xFE <cmd>`, plus one argument byte for `0x80`) is carried out when
its last byte has arrived and answered `0x55 0xFF` + ACK `0xAA`, or + two
data bytes (high & 0x03, low) for a sensor read, after the reply's own
line time. So one exchange takes (request + reply) x 10 / baud seconds,
`line_time` sums them. A host at another baud rate gets garbage, as from a
real UART. A byte that does not fit the header is echoed and ignored; an
unknown command is echoed and not answered.

Strict on purpose, so a lenient driver shows up here rather than on a
board: a command byte outside the table below (sensor mode 3, a motor or
power code with its low bits set, ...) and a select mask with bits above
0x0F are echoed, counted in `unknown` and neither carried out nor answered
(the driver must notice the missing reply, not get a guess).

Commands (bits 7-5 command, 4-2 parameter, 1-0 extra):
    0x00 ping; 0x20|(n-1)<<2|mode read sensor n (mode 0 normal, 1 max,
    2 min: this emulator samples on demand, so all three read the same);
    0x40 on, 0x44 off (brake), 0x48 reverse, 0x4C this way, 0x50 that
    way, 0x54 coast, for the selected outputs; 0x60|level<<2 power 0..7 of
    the selected outputs (7 at power-up); 0x80 + mask select outputs
    (A=1 B=2 C=4 D=8; none at power-up); 0xC0 / 0xC1 user LED on / off;
    0xC4 beep.

The robot: one robot of a sim World (index `index`), pose in mm and degrees
(0 = north, clockwise), mirrored into the world's Q8 position. The `left`
and `right` outputs drive the wheels at power x `mm_s_per_level` mm/s
(forward when their direction is `*_forward`) in the time of `clock` (wall
time by default; a SimClock for tests that must not depend on load); a wheel
pushed into an object, a robot or the arena's edge does not move the robot.
Touch switches (`touch_ports`, bearing -> port) are closed, reading near 0,
when the patch one patch away in their direction is object, wall or another
robot, else open, near 1023. Light sensors (`light_ports`) read
`dark - field x light_step` of the patch one patch away in their direction
(lower is brighter). Unwired ports float high (1023). The user LED is the
beacon: on adds the robot's field to the world (Signal), off removes it.
"""

from __future__ import annotations

from sim_backend.emulators.ptyport import Emulator
from sim_backend.emulators.worldrobot import SimClock, SystemClock, WorldRobot
from sim_backend.world import FREE

FRAME_1, FRAME_2 = 0x54, 0xFE
ANSWER = bytes((0x55, 0xFF))
OK = 0xAA
PORT_BITS = {"A": 1, "B": 2, "C": 4, "D": 8}
THISWAY, THATWAY = 1, -1

# parser states
IDLE, GOT_54, GOT_FE, GOT_SELECT = range(4)


class GoGoEmulator(WorldRobot, Emulator):
    bits_per_byte = 10

    def __init__(self, world=None, index: int = 0, baud: int = 9600,
                 patch_mm: float = 50.0, heading: float = 0.0, path: str | None = None,
                 touch_ports: dict[int, int] | None = None,
                 light_ports: dict[int, int] | None = None,
                 dark: int = 800, light_step: int = 40, left: str = "A", right: str = "B",
                 left_forward: str = "thisway", right_forward: str = "thisway",
                 mm_s_per_level: float = 20.0, wheel_base_mm: float = 100.0,
                 clock: SimClock | SystemClock | None = None) -> None:
        super().__init__(baud, path)
        self.clock = clock if clock is not None else SystemClock()
        self.world = world
        self.index = index
        self.patch_mm = patch_mm
        self.touch_ports = dict(touch_ports if touch_ports is not None
                                else {0: 1, 90: 2, 180: 3, 270: 4})
        self.light_ports = dict(light_ports if light_ports is not None else {0: 5})
        self.dark = dark
        self.light_step = light_step
        self.wheels = {"left": PORT_BITS[left.upper()], "right": PORT_BITS[right.upper()]}
        self.forward_dir = {"left": THISWAY if left_forward == "thisway" else THATWAY,
                            "right": THISWAY if right_forward == "thisway" else THATWAY}
        self.mm_s_per_level = mm_s_per_level
        self.wheel_base_mm = wheel_base_mm
        if world is not None:
            self.x_mm = world.xs[index] * patch_mm / 256.0
            self.y_mm = world.ys[index] * patch_mm / 256.0
        else:
            self.x_mm = self.y_mm = 0.0
        self.theta = heading % 360
        # the board
        self.selected = 0
        self.motor_on = {b: False for b in PORT_BITS.values()}
        self.motor_dir = {b: THISWAY for b in PORT_BITS.values()}
        self.motor_power = {b: 7 for b in PORT_BITS.values()}
        self.led = 0
        self.beeps = 0
        self.commands = 0
        self.unknown = 0
        self.beacon_src: tuple[int, int] | None = None
        self._state = IDLE
        self._cmd = 0
        self._t = self.clock.now()
        # faults for tests
        self.noise_next = b""           # written before the next request's echo
        self.garbage_next = b""         # written between the next echo and its reply
        self.truncate_next = 0          # cut the next reply to this many bytes
        self.corrupt_echo_next = 0      # echo the next N commands' last byte wrongly
        self.mute_next = 0              # neither echo nor answer the next N commands

    # -- physics -----------------------------------------------------------------

    def wheel_speed(self, side: str) -> float:
        bit = self.wheels[side]
        if not self.motor_on[bit]:
            return 0.0
        sign = 1 if self.motor_dir[bit] == self.forward_dir[side] else -1
        return sign * self.motor_power[bit] * self.mm_s_per_level

    def _integrate(self) -> None:
        now = self.clock.now()
        dt = now - self._t
        self._t = now
        vl, vr = self.wheel_speed("left"), self.wheel_speed("right")
        if dt <= 0 or (vl == 0 and vr == 0):
            return
        self._drive(vl * dt, vr * dt, self.wheel_base_mm)

    def reading(self, port: int) -> int:
        """What sensor port 1..8 reads now (10 bits)."""
        for bearing, p in self.touch_ports.items():
            if p == port:
                return (3 + port) if self._switch_closed(bearing) else (1019 + port % 4)
        for bearing, p in self.light_ports.items():
            if p == port:
                f = 0
                if self.world is not None:
                    q = self._look(bearing)
                    if self.world.inside(*q):
                        f = self.world.field[self.world.idx(*q)]
                return max(0, min(1023, self.dark - f * self.light_step))
        return 1023                      # nothing wired: the input floats high

    def _switch_closed(self, bearing: float) -> bool:
        w = self.world
        if w is None:
            return False
        q = self._look(bearing)
        if not w.inside(*q):
            return True
        k = w.idx(*q)
        here = self._patch(self.x_mm, self.y_mm)
        return w.obj[k] != FREE or (w.occ[k] > 0 and q != here)

    # -- the serial side ------------------------------------------------------------

    def on_bytes(self, data: bytes) -> None:
        for c in data:
            self._byte(c)

    def _byte(self, c: int) -> None:
        complete = False
        arg = -1
        if self._state == IDLE:
            if c == FRAME_1:
                self._state = GOT_54
        elif self._state == GOT_54:
            self._state = GOT_FE if c == FRAME_2 else (GOT_54 if c == FRAME_1 else IDLE)
        elif self._state == GOT_FE:
            self._cmd = c
            if c == 0x80:
                self._state = GOT_SELECT
            else:
                complete = True
                self._state = IDLE
        else:
            arg = c
            complete = True
            self._state = IDLE
        if self.mute_next:               # a board that hears nothing: no echo either
            if complete:
                self.mute_next -= 1
            return
        if self.noise_next and self._state == GOT_54:
            self.pty.write(self.noise_next)
            self.noise_next = b""
        echo = c
        if complete and self.corrupt_echo_next:
            self.corrupt_echo_next -= 1
            echo = c ^ 0x10
        self.reply(bytes([echo]))        # one byte time on the wire
        if complete:
            self._execute(self._cmd, arg)

    def _answer(self, payload: bytes) -> None:
        out = self.garbage_next + ANSWER + payload
        self.garbage_next = b""
        if self.truncate_next:
            out = out[: self.truncate_next]
            self.truncate_next = 0
        self.reply(out)

    def _execute(self, cmd: int, arg: int) -> None:
        self.commands += 1
        self._integrate()
        group, param, extra = cmd >> 5, (cmd >> 2) & 7, cmd & 3
        if cmd == 0x00:
            self._answer(bytes([OK]))
        elif group == 1 and extra <= 2:  # 0x20: read sensor param+1 (mode 3: none)
            v = self.reading(param + 1)
            self._answer(bytes([(v >> 8) & 0x03, v & 0xFF]))
        elif group == 2 and extra == 0 and param <= 5:
            for bit in PORT_BITS.values():
                if not self.selected & bit:
                    continue
                if param == 0:
                    self.motor_on[bit] = True
                elif param in (1, 5):     # off (brake) and coast both stop here
                    self.motor_on[bit] = False
                elif param == 2:
                    self.motor_dir[bit] = -self.motor_dir[bit]
                elif param == 3:
                    self.motor_dir[bit] = THISWAY
                else:
                    self.motor_dir[bit] = THATWAY
            self._answer(bytes([OK]))
        elif group == 3 and extra == 0:  # 0x60: power
            for bit in PORT_BITS.values():
                if self.selected & bit:
                    self.motor_power[bit] = param
            self._answer(bytes([OK]))
        elif cmd == 0x80 and 0 <= arg <= 0x0F:
            self.selected = arg
            self._answer(bytes([OK]))
        elif cmd in (0xC0, 0xC1):
            self.led = 1 if cmd == 0xC0 else 0
            self._beacon(self.led)
            self._answer(bytes([OK]))
        elif cmd == 0xC4:
            self.beeps += 1
            self._answer(bytes([OK]))
        else:
            self.unknown += 1             # echoed, not answered

