"""GoGo Board (serial generation) over its binary protocol, and a firmware HAL on top.

`GoGoBoard` is the protocol client (../shared/design/protocols.md, docs/serial.md):
9600 baud 8N1; the host sends `0x54 0xFE <cmd> [arg]`, the board echoes every
byte it receives, then answers `0x55 0xFF` followed by ACK `0xAA` or, for a
sensor read, two data bytes (high & 0x03, low) of a 10-bit value.

Every transaction: stale input is flushed, the request written, and the
reply read against a deadline (every read has a timeout). The echo must come
back exactly; junk before the echo or between the echo and the `0x55 0xFF`
header is skipped (counted in `junk`). A missing, garbled or truncated
reply is retried `retries` times (not for `reverse`, which is not
idempotent, once the echo proved the board got it), then raises:

- SerialTimeout: nothing came back at all (board off, wrong port);
- ProtocolError "no echo of ...": bytes came back but never the echo: wrong
  baud rate (a GoGo board runs at 9600 8N1 only) or not a GoGo board;
- ProtocolError "bad reply to ...": the echo was right but the reply was not
  what the command expects (the message names what was expected and what came);
- SerialPortLost (a SerialTimeout): the port failed or vanished; the next
  command tries to reopen it, so a board that comes back (USB replugged)
  works again. No raw termios.error / OSError ever escapes: every port error
  is converted where the port is used.

They are the serial package's errors (bridge/serial/errors.py, under
SerialLinkError and bridge.errors.BridgeError), as the Khepera driver's are;
an argument out of the protocol's range is a UsageError.

`GoGoBody` is the HAL of firmware_logic/hal.py for a differential-drive
robot built on a GoGo board, its firmware running on the host per robot
(like KheperaBody). Wiring (configurable): touch switches on sensor ports
(a closed switch reads near 0, an open one near 1023; default front 1,
right 2, rear 3, left 4), the left and right motors on outputs A and B,
light sensors (lower is brighter; default one facing forward on port 5)
give the field, the user LED is the beacon.

Limitation: a GoGo board has no wheel encoders, so the pose is dead
reckoning from the commanded motion (power level x calibrated mm/s per
level x time the motors were on). It drifts with battery voltage, wheel
slip and a wheel pushed against an obstacle; calibrate `mm_s_per_level`
and `wheel_base_mm` per robot, and expect the error to grow with distance.
"""

from __future__ import annotations

import logging
import math
import time
from types import TracebackType

import serial

from bridge.errors import UsageError
from bridge.serial.errors import (PORT_ERRORS, PortClosedError, ProtocolError,
                                  SerialLinkError, SerialOpenError, SerialPortLost,
                                  SerialTimeout)
from bridge.serial.hostbody import DRIVE, TURN, Clock, HostBody, Phase
from bridge.serial.transport import open_serial, resolve_url
from firmware_logic import fixedpoint as fx
from firmware_logic.hal import NOTHING, OBJECT, WALL

log = logging.getLogger(__name__)

BAUD = 9600
BITS_PER_BYTE = 10                      # 8N1: start + 8 data + stop

HEADER = b"\x54\xfe"
REPLY_HEADER = b"\x55\xff"
ACK = 0xAA

PING = 0x00
SENSOR = 0x20
MOTOR_ON = 0x40
MOTOR_OFF = 0x44
MOTOR_REVERSE = 0x48
MOTOR_THISWAY = 0x4C
MOTOR_THATWAY = 0x50
MOTOR_COAST = 0x54
POWER = 0x60
SELECT = 0x80
LED_ON = 0xC0
LED_OFF = 0xC1
BEEP = 0xC4

NORMAL, MAX, MIN = 0, 1, 2              # sensor read modes
OUTPUTS = {"A": 1, "B": 2, "C": 4, "D": 8}

NAMES = {PING: "ping", MOTOR_ON: "motor on", MOTOR_OFF: "motor off",
         MOTOR_REVERSE: "motor reverse", MOTOR_THISWAY: "motor thisway",
         MOTOR_THATWAY: "motor thatway", MOTOR_COAST: "motor coast", SELECT: "select outputs",
         LED_ON: "LED on", LED_OFF: "LED off", BEEP: "beep"}

MAX_JUNK = 32                           # junk bytes tolerated around the echo / reply


def hexs(data: bytes) -> str:
    return " ".join("%02x" % b for b in data) or "nothing"


def sensor_command(n: int, mode: int = NORMAL) -> int:
    if not 1 <= n <= 8:
        raise UsageError("sensor port %r: a GoGo board has ports 1..8" % (n,))
    if mode not in (NORMAL, MAX, MIN):
        raise UsageError("sensor mode %r: 0 normal, 1 max, 2 min" % (mode,))
    return SENSOR | (n - 1) << 2 | mode


def output_mask(ports: str | int) -> int:
    """'AB' -> 3; an int mask 0..15 passes through."""
    if isinstance(ports, int):
        if not 0 <= ports <= 15:
            raise UsageError("output mask %r: A=1 B=2 C=4 D=8, 0..15" % (ports,))
        return ports
    mask = 0
    for p in ports.upper():
        if p not in OUTPUTS:
            raise UsageError("output %r: a GoGo board has outputs A, B, C, D" % (p,))
        mask |= OUTPUTS[p]
    return mask


class _Attempt:
    """What one try of a transaction saw."""

    __slots__ = ("buf", "echo_ok", "value", "done", "why")

    def __init__(self) -> None:
        self.buf = b""
        self.echo_ok = False
        self.value: int | None = None
        self.done = False
        self.why = ""


class GoGoBoard:
    """The GoGo serial protocol over any pyserial port or URL.

    `url`: a device path, `gogo:///dev/ttyUSB0?baud=9600`, or a pyserial URL.
    `timeout`: the deadline of one try; `quiet`: a try with some bytes ends
    early when nothing more arrives for this long (a truncated reply).
    """

    def __init__(self, url: str, baud: int = BAUD, timeout: float = 0.3,
                 retries: int = 2, quiet: float = 0.1) -> None:
        try:
            port, opts = resolve_url(url, "gogo", BAUD)
        except SerialOpenError as err:
            raise SerialOpenError(str(err)) from err
        self.url = url
        self.port = port
        self.baud = int(opts.get("baud", baud))
        self.timeout = timeout
        self.retries = retries
        self.quiet = quiet
        self.byte_time = BITS_PER_BYTE / self.baud
        self.retried = 0                # tries after the first, over all commands
        self.junk = 0                   # bytes skipped around echoes and replies
        self.reopened = 0
        self.transactions = 0
        self.last_reply_at = 0.0        # monotonic time the last full reply arrived
        self.ser: serial.SerialBase | None = None
        self._closed = False
        self._open()

    def __enter__(self) -> "GoGoBoard":
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def close(self) -> None:
        """Idempotent; never raises (the port may already be gone)."""
        self._closed = True
        self._drop()

    def _open(self) -> None:
        try:
            self.ser = open_serial(self.port, self.baud, 0.02)
        except SerialOpenError as err:
            raise SerialOpenError("GoGo board: %s" % err) from err

    def _drop(self) -> None:
        ser, self.ser = self.ser, None
        if ser is not None:
            try:
                ser.close()
            except Exception as err:     # closing a dead port: nothing left to do
                log.debug("GoGo board on %s: close: %s", self.port, err)

    def _ensure_open(self, what: str) -> serial.SerialBase:
        if self._closed:
            raise PortClosedError("GoGo board on %s: port is closed (%s)" % (self.port, what))
        if self.ser is None:
            try:
                self._open()
            except SerialOpenError as err:
                raise SerialPortLost("GoGo board on %s is gone (%s): %s"
                                   % (self.port, what, err)) from err
            self.reopened += 1
            log.info("GoGo board on %s: port reopened", self.port)
        assert self.ser is not None
        return self.ser

    # -- one transaction --------------------------------------------------------------

    @staticmethod
    def _parse(at: _Attempt, req: bytes, data: bool) -> None:
        buf = at.buf
        i = buf.find(req)
        if i < 0:
            at.why = "echo"
            return
        at.echo_ok = True
        rest = buf[i + len(req):]
        j = rest.find(REPLY_HEADER)
        if j < 0:
            at.why = "header"
            return
        body = rest[j + 2:]
        need = 2 if data else 1
        if len(body) < need:
            at.why = "short"
            return
        if data:
            hi, lo = body[0], body[1]
            if hi & 0xFC:
                at.why = "high byte %02x has bits above 0x03" % hi
                at.done = True
                return
            at.value = hi << 8 | lo
        elif body[0] != ACK:
            at.why = "%02x instead of ACK aa" % body[0]
            at.done = True
            return
        at.done = True
        at.why = ""

    def _try(self, ser: serial.SerialBase, req: bytes, data: bool) -> _Attempt:
        at = _Attempt()
        ser.reset_input_buffer()
        ser.write(req)
        now = time.monotonic()
        deadline = now + self.timeout
        last = now
        while now < deadline:
            chunk = ser.read(ser.in_waiting or 1)
            now = time.monotonic()
            if chunk:
                at.buf += chunk
                last = now
                self._parse(at, req, data)
                if at.done:
                    break
                if len(at.buf) > len(req) + MAX_JUNK + 4:
                    break               # far more than any reply: give up this try
            elif at.buf and now - last >= self.quiet:
                break                   # something came, then nothing: truncated
        if at.value is not None or (at.done and not at.why):
            self.last_reply_at = time.monotonic()
            skipped = len(at.buf) - len(req) - (4 if data else 3)
            self.junk += max(0, skipped)
        return at

    def transact(self, cmd: int, arg: int | None = None, data: bool = False,
                 idempotent: bool = True) -> int | None:
        """Send one command; return the 10-bit value (data=True) or None (ACK)."""
        req = HEADER + bytes([cmd]) + (b"" if arg is None else bytes([arg]))
        what = "%s (%s)" % (self._name(cmd), hexs(req))
        want = ("55 ff then two data bytes (high <= 03, low)" if data
                else "55 ff then ACK aa")
        seen: list[_Attempt] = []
        self.transactions += 1
        for attempt in range(self.retries + 1):
            if attempt:
                self.retried += 1
            ser = self._ensure_open(what)
            try:
                at = self._try(ser, req, data)
            except serial.SerialTimeoutException as err:
                raise SerialTimeout("GoGo board on %s: could not write %s within %.2f s: %s"
                                  % (self.port, what, self.timeout, err)) from err
            except PORT_ERRORS as err:
                self._drop()
                raise SerialPortLost("GoGo board on %s: port failed during %s: %s"
                                   % (self.port, what, err)) from err
            if at.done and not at.why:
                return at.value
            seen.append(at)
            if at.echo_ok and not idempotent:
                break                   # the board got it: a retry would apply it twice
        heard = [a for a in seen if a.buf]
        tries = len(seen)
        if not heard:
            raise SerialTimeout("GoGo board on %s did not answer %s within %.2f s (%d tries); "
                              "is it powered and on this port at 9600 baud 8N1?"
                              % (self.port, what, self.timeout, tries))
        if not any(a.echo_ok for a in seen):
            raise ProtocolError("GoGo board on %s: no echo of %s in %d tries (last got %s); "
                                "a GoGo board echoes every byte at 9600 baud 8N1, this port "
                                "is at %d baud: check the baud rate and that it is a GoGo"
                                % (self.port, what, tries, hexs(heard[-1].buf[:24]),
                                   self.baud))
        last = [a for a in seen if a.echo_ok][-1]
        got = last.buf[last.buf.find(req) + len(req):]
        detail = {"header": "no 55 ff header", "short": "truncated"}.get(last.why, last.why)
        raise ProtocolError("GoGo board on %s: bad reply to %s after its echo: expected %s, "
                             "got %s (%s; %d %s%s)"
                             % (self.port, what, want, hexs(got[:24]), detail, tries,
                                "try" if tries == 1 else "tries",
                                "" if idempotent else ", not retried: not idempotent"))

    @staticmethod
    def _name(cmd: int) -> str:
        if cmd & 0xE0 == SENSOR:
            return "read sensor %d mode %d" % (((cmd >> 2) & 7) + 1, cmd & 3)
        if cmd & 0xE0 == POWER:
            return "power %d" % ((cmd >> 2) & 7)
        return NAMES.get(cmd, "command %02x" % cmd)

    # -- commands -------------------------------------------------------------------------

    def ping(self) -> None:
        self.transact(PING)

    def sensor(self, n: int, mode: int = NORMAL) -> int:
        """The 10-bit reading (0..1023) of sensor port n (1..8)."""
        v = self.transact(sensor_command(n, mode), data=True)
        assert v is not None
        return v

    def select(self, ports: str | int) -> None:
        """Talk to these outputs from now on: 'AB', 'A', or a mask (A=1 B=2 C=4 D=8)."""
        self.transact(SELECT, output_mask(ports))

    def on(self) -> None:
        self.transact(MOTOR_ON)

    def off(self) -> None:
        self.transact(MOTOR_OFF)

    def reverse(self) -> None:
        self.transact(MOTOR_REVERSE, idempotent=False)

    def thisway(self) -> None:
        self.transact(MOTOR_THISWAY)

    def thatway(self) -> None:
        self.transact(MOTOR_THATWAY)

    def coast(self) -> None:
        self.transact(MOTOR_COAST)

    def power(self, level: int) -> None:
        if not 0 <= level <= 7:
            raise UsageError("power level %r: 0..7" % (level,))
        self.transact(POWER | level << 2)

    def led(self, on: bool) -> None:
        self.transact(LED_ON if on else LED_OFF)

    def beep(self) -> None:
        self.transact(BEEP)


# -- the body ------------------------------------------------------------------------------

THISWAY = "thisway"
THATWAY = "thatway"


def _angle(a: float) -> float:
    """Into -180..180."""
    return (a + 180) % 360 - 180


class GoGoBody(HostBody):
    """The firmware HAL over a GoGo board on a differential-drive robot.

    Bearings in `touch_ports` / `light_ports` are relative to the robot's
    heading, clockwise degrees (0 front, 90 right); values are sensor ports
    1..8. `left` / `right` are the motor outputs; `*_forward` says which
    direction command drives that wheel forward (mirrored motors usually
    need one thisway and one thatway). Positions are Q8 patches of `patch_mm`.
    `arena` (the world's half size in patches), when given, makes a touch
    outside it a WALL rather than the object.

    Motions are timed (no encoders): a phase turns the motors on and notes
    the time; each later tick checks it, and when its end falls before the
    next tick (`tick_s` away) waits out that last part of a tick and turns
    them off, so no call waits longer than one tick per phase.
    """

    def __init__(self, board: GoGoBoard, node: int, link: object | None = None,
                 patch_mm: float = 50.0,
                 touch_ports: dict[int, int] | None = None,
                 light_ports: dict[int, int] | None = None,
                 touch_threshold: int = 512, dark: int = 800, light_step: int = 40,
                 left: str = "A", right: str = "B", left_forward: str = THISWAY,
                 right_forward: str = THISWAY, power: int = 7, mm_s_per_level: float = 20.0,
                 wheel_base_mm: float = 100.0, x_mm: float = 0.0, y_mm: float = 0.0,
                 heading: float = 0.0, arena: int | None = None, tick_s: float = 0.05,
                 clock: Clock | None = None) -> None:
        super().__init__(node, link, patch_mm, x_mm, y_mm, heading, clock)
        self.b = board
        self.touch_ports = dict(touch_ports if touch_ports is not None
                                else {0: 1, 90: 2, 180: 3, 270: 4})
        self.light_ports = dict(light_ports if light_ports is not None else {0: 5})
        for p in list(self.touch_ports.values()) + list(self.light_ports.values()):
            sensor_command(p)           # validates 1..8
        if not self.light_ports:
            raise UsageError("GoGoBody needs at least one light sensor port for the field")
        self.touch_threshold = touch_threshold
        self.dark = dark
        self.light_step = light_step
        if left_forward not in (THISWAY, THATWAY) or right_forward not in (THISWAY, THATWAY):
            raise UsageError("left_forward / right_forward: 'thisway' or 'thatway'")
        self.left, self.right = left.upper(), right.upper()
        self.fwd = {self.left: left_forward, self.right: right_forward}
        self.both = output_mask(self.left + self.right)
        if not 0 <= power <= 7:
            raise UsageError("power level %r: 0..7" % (power,))
        self.level = power
        self.mm_s = power * mm_s_per_level
        self.wheel_base_mm = wheel_base_mm
        self.arena = arena
        self.tick_s = tick_s
        self.moving_seconds = 0.0
        self._dirs: dict[str, str | None] = {self.left: None, self.right: None}
        self._before: int | None = None    # light field before the last forward move
        self._moved = False                # a forward move's drive ended since
        self._sample_gradient = False      # the current motion is a forward move
        self._stop_owed = False            # a lost port may have left the motors on
        self._setup()

    def _setup(self) -> None:
        """Put the board in a known state (also after it was replugged: a
        board that lost power is back at power 7, nothing selected)."""
        self._dirs = {self.left: None, self.right: None}
        self.b.ping()
        self.b.select(self.both)
        self.b.off()
        self.b.power(self.level)
        self.b.led(bool(self.beacon_on))
        self._stop_owed = False
        self._seen_reopen = self.b.reopened

    def _replugged(self) -> bool:
        return self.b.reopened != self._seen_reopen

    # -- motion by dead reckoning -------------------------------------------------------

    def _resume(self) -> None:
        if self._stop_owed or (self._replugged() and not self.phases):
            self._setup()

    def _direction(self, port: str, forward: bool) -> None:
        fwd = self.fwd[port]
        want = fwd if forward else (THATWAY if fwd == THISWAY else THISWAY)
        if self._dirs[port] == want:
            return
        self._dirs[port] = None         # unknown until the board confirmed it
        self.b.select(port)
        if want == THISWAY:
            self.b.thisway()
        else:
            self.b.thatway()
        self._dirs[port] = want

    def _wire(self) -> float:
        """How long a 3-byte command or reply takes on the wire (0 on a
        simulated clock, where bytes take no time)."""
        return 3 * self.b.byte_time if self.clock.wire_time else 0.0

    def _motors_on(self, ph: Phase) -> bool:
        """Start the phase's wheels; False if there is nothing to do."""
        if self.mm_s <= 0:
            return False
        if self._replugged():
            self._setup()
        if ph.kind == TURN:
            err = _angle(ph.heading - self.theta)
            if abs(err) < 1.0:
                return False
            ph.sign = 1.0 if err > 0 else -1.0
            ph.seconds = math.radians(abs(err)) * self.wheel_base_mm / 2 / self.mm_s
            left_fwd, right_fwd = err > 0, err < 0
        else:
            if ph.mm <= 0:
                return False
            ph.seconds = ph.mm / self.mm_s
            left_fwd = right_fwd = True
            if self._sample_gradient:
                # facing the way it will drive now: the field before the move
                port = next(iter(self.light_ports.values()))
                self._before = self._field_from(self.b.sensor(port))
        self._direction(self.left, left_fwd)
        self._direction(self.right, right_fwd)
        self.b.select(self.both)
        try:
            self.b.on()
        except SerialLinkError:
            self._stop_owed = True      # the board may have got it: stop on the next tick
            raise
        # `on` took effect when its last byte arrived, before its 3-byte reply
        ph.t_on = self.clock.now() - self._wire()
        return True

    def _motors_off(self, ph: Phase) -> None:
        """Stop the wheels and add what they did to the pose. If the port is
        lost here, the board keeps its last command (the motors may still
        run) and the move is not added to the pose."""
        sent = self.clock.now()
        try:
            self.b.off()
        except SerialLinkError:
            self._stop_owed = True
            raise
        # `off` takes effect when its 3rd byte arrives
        ran = max(0.0, sent + self._wire() - ph.t_on)
        self.moving_seconds += ran
        if ph.kind == TURN:
            turned = math.degrees(ran * self.mm_s * 2 / self.wheel_base_mm)
            self.theta = (self.theta + ph.sign * turned) % 360
        else:
            d = ran * self.mm_s
            th = math.radians(self.theta)
            self.x_mm += d * math.sin(th)
            self.y_mm += d * math.cos(th)
            self._moved = self._sample_gradient

    def _advance(self) -> None:
        try:
            while self.phases:
                ph = self.phases[0]
                if ph.t_on < 0 and not self._motors_on(ph):
                    self.phases.pop(0)
                    continue
                left = ph.t_on + ph.seconds - self._wire() - self.clock.now()
                if left > self.tick_s:
                    ph.ticks += 1
                    return              # the next tick comes before the end
                self.clock.sleep(left)  # the end falls within this tick: wait for it
                self._motors_off(ph)
                self.phases.pop(0)
        except SerialLinkError:
            self.phases.clear()         # the motion is lost with the port; see _resume
            raise

    _begin = _advance

    def turn_to(self, heading: float) -> None:
        """Start turning in place to `heading` (degrees); see begin_tick()."""
        self._start([Phase(TURN, heading=heading % 360)])

    def drive(self, mm: float) -> None:
        """Start driving `mm` straight ahead; see begin_tick()."""
        self._start([Phase(DRIVE, mm=mm)] if mm > 0 else [])

    # -- sensing ----------------------------------------------------------------------

    # x() / y(): HostBody

    @staticmethod
    def _nearest(ports: dict[int, int], rel: float) -> tuple[int, float]:
        best, dist = -1, 999.0
        for bearing, port in ports.items():
            d = abs(_angle(rel - bearing))
            if d < dist:
                best, dist = port, d
        return best, dist

    def _sensor(self, port: int) -> int:
        return self._reading(port, lambda: self.b.sensor(port))     # type: ignore[return-value]

    def touching(self, port: int) -> bool:
        """A closed switch reads near 0, an open one near 1023."""
        return self._sensor(port) < self.touch_threshold

    def probe(self, heading: int) -> int:
        port, dist = self._nearest(self.touch_ports, _angle(heading - self.theta))
        if dist > 50 or not self.touching(port):
            return NOTHING
        if self.arena is not None:
            px = fx.patch(self.x() + fx.dx(heading % 360, fx.ONE))
            py = fx.patch(self.y() + fx.dy(heading % 360, fx.ONE))
            if max(abs(px), abs(py)) > self.arena:
                return WALL
        return OBJECT

    def _field_from(self, v: int) -> int:
        return max(0, self.dark - v) // self.light_step

    def _light(self, port: int) -> int:
        return self._field_from(self._sensor(port))

    def field_ahead(self, heading: int) -> int:
        port, dist = self._nearest(self.light_ports, _angle(heading - self.theta))
        if dist <= 50:
            return self._light(port)
        # no light sensor faces that way: the field around the robot is the estimate
        return self.field_here()

    def field_here(self) -> int:
        return min(self._light(p) for p in self.light_ports.values())

    def uphill(self) -> int:
        if len(self.light_ports) == 1:
            # one sensor: follow the gradient along the way just driven
            (bearing, port), = self.light_ports.items()
            now = self._light(port)
            up = self._moved and self._before is not None and now > self._before
            if not up:
                return -1
            return int(round(((self.theta + bearing) % 360) / 45.0)) * 45 % 360
        fields = {b: self._light(p) for b, p in self.light_ports.items()}
        best = max(fields, key=lambda b: fields[b])
        if fields[best] <= min(fields.values()):
            return -1
        return int(round(((self.theta + best) % 360) / 45.0)) * 45 % 360

    def holding(self) -> int:
        if self.claimed < 0:
            return 0
        return 1 if self.probe(self.claimed) == OBJECT else 0

    # -- acting --------------------------------------------------------------------------

    def forward(self, heading: int, step: int) -> None:
        self._sample_gradient = len(self.light_ports) == 1
        self._moved = False
        self._start([Phase(TURN, heading=heading % 360),
                     Phase(DRIVE, mm=step * self.patch_mm / fx.ONE)])

    def claim(self, heading: int) -> None:
        self.claimed = heading
        self._start([Phase(TURN, heading=heading % 360)])

    def carry(self, dx: int, dy: int) -> None:
        if dx == 0 and dy == 0:
            return
        self._sample_gradient = False
        self._moved = False
        self._start([Phase(TURN, heading=math.degrees(math.atan2(dx, dy)) % 360),
                     Phase(DRIVE, mm=math.hypot(dx, dy) * self.patch_mm)])

    def beacon(self, on: int) -> None:
        self.b.led(bool(on))
        self.beacon_on = 1 if on else 0

    # -- messages ---------------------------------------------------------------------------

    # send / recv: HostBody
