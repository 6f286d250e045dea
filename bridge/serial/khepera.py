"""Khepera II over its RS-232 ASCII protocol, and a firmware HAL on top.

`KheperaII` is the protocol client: one upper-case command letter with
comma-separated arguments and CR; the reply is the lower-case letter with
values, CR LF. Every read has a deadline; stale input is flushed before each
command. Line noise (a garbled, truncated or missing reply, and a single
`Command not found` or `z,Protocol error`: the robot heard a garbled
request) is retried `retries` times; then ProtocolError / SerialTimeout
names the command (and, when nothing sensible ever came back, suggests the
baud rate, which on a Khepera II is set by its mode jumper). A port that
fails or vanishes raises SerialPortLost (a SerialTimeout) and is reopened
on the next call, so a robot plugged back in goes on.

`KheperaBody` is the HAL of firmware_logic/hal.py for a Khepera II whose
firmware runs on the host (the "remote brain" of the thesis's hardware
option): odometry from the `H` counters (1 pulse = 1/12 mm, wheel base
53 mm) gives the pose; proximity `N` above `touch_threshold` in a direction
is a touch (the object); ambient light `O` gives the field (a lit beacon LED,
`L`, is a stationary robot's field source); `D` drives the wheels. Motions
are steered tick by tick (bridge/serial/hostbody.py): each tick reads `H`
once and sets the speeds that cover half the rest by the next tick.
"""

from __future__ import annotations

import logging
import math
import time
from types import TracebackType
from typing import Callable, TypeVar

import serial

from bridge.serial.errors import (PORT_ERRORS, PortClosedError, ProtocolError,
                                  SerialOpenError, SerialPortLost, SerialTimeout)
from bridge.serial.hostbody import DRIVE, TURN, Clock, HostBody, Phase
from bridge.serial.transport import open_serial, resolve_url
from firmware_logic import fixedpoint as fx
from firmware_logic.hal import NOTHING, OBJECT

log = logging.getLogger(__name__)

PULSE_MM = 1.0 / 12.0
WHEEL_BASE_MM = 53.0
SPEED_PERIOD_S = 0.01                   # `D` speeds are pulses per 10 ms
APPROACH_TICKS = 2
# sensor bearings relative to the heading, clockwise degrees (0 = left side)
PROX_BEARINGS = (-90, -45, -10, 10, 45, 90, 170, -170)
BAUDS = (9600, 19200, 38400, 57600, 115200)
MAX_LINE = 200                          # no reply is longer: a line this long is noise
# what the robot answers to a request it could not parse; on a noisy line
# that is a garbled request, so it is retried like a garbled reply
REFUSALS = (b"Command not found", b"z,Protocol error")

T = TypeVar("T")


class KheperaII:
    def __init__(self, url: str, baud: int = 38400, timeout: float = 0.5,
                 retries: int = 2) -> None:
        port, opts = resolve_url(url, "khepera", 38400)
        self.port = port
        self.baud = int(opts.get("baud", baud))
        self.timeout = timeout
        self.retries = retries
        self.retried = 0                # tries after the first, over all commands
        self.reopened = 0
        self._closed = False
        self._rx = bytearray()          # bytes read past the last line
        self.ser: serial.SerialBase | None = None
        self.ser = self._open()

    def __enter__(self) -> "KheperaII":
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def _open(self) -> serial.SerialBase:
        return open_serial(self.port, self.baud, 0.02, stopbits=serial.STOPBITS_TWO)

    def close(self) -> None:
        """Idempotent; never raises (the port may already be gone)."""
        self._closed = True
        self._drop()

    def _drop(self) -> None:
        ser, self.ser = self.ser, None
        self._rx.clear()
        if ser is not None:
            try:
                ser.close()
            except Exception as err:     # closing a dead port: nothing left to do
                log.debug("Khepera on %s: close: %s", self.port, err)

    def _ensure_open(self, what: str) -> serial.SerialBase:
        if self._closed:
            raise PortClosedError("Khepera on %s: port is closed (%s)" % (self.port, what))
        if self.ser is None:
            try:
                self.ser = self._open()
            except SerialOpenError as err:
                raise SerialPortLost("Khepera on %s is gone (%s): %s"
                                     % (self.port, what, err)) from err
            self.reopened += 1
            log.info("Khepera on %s: port reopened", self.port)
        return self.ser

    def _readline(self, ser: serial.SerialBase, deadline: float) -> bytes | None:
        """One line (up to LF, or MAX_LINE bytes of noise), or None at the deadline."""
        while True:
            i = self._rx.find(b"\n")
            if i >= 0 or len(self._rx) >= MAX_LINE:
                end = i + 1 if i >= 0 else MAX_LINE
                line = bytes(self._rx[:end])
                del self._rx[:end]
                return line
            if time.monotonic() >= deadline:
                return None
            # the port's read timeout (0.02 s) bounds this read
            self._rx += ser.read(max(1, ser.in_waiting))

    def _exchange(self, letter: str, args: tuple[int, ...],
                  parse: Callable[[list[bytes]], T | None]) -> T:
        """Send one command; return parse(reply fields) of the first reply
        starting with the lower-case letter that parse accepts (not None)."""
        req = (",".join([letter] + [str(int(a)) for a in args]) + "\r").encode("ascii")
        what = req.decode().strip()
        want = letter.lower().encode("ascii")
        seen: list[bytes] = []
        for attempt in range(self.retries + 1):
            if attempt:
                self.retried += 1
            ser = self._ensure_open(what)
            try:
                ser.reset_input_buffer()
                self._rx.clear()
                ser.write(req)
                deadline = time.monotonic() + self.timeout
                while True:
                    line = self._readline(ser, deadline)
                    if line is None:
                        break
                    text = line.strip()
                    seen.append(text)
                    parts = text.split(b",")
                    if parts[0] == want:
                        value = parse(parts[1:])
                        if value is not None:
                            return value
                        break           # its reply, garbled: no other one is coming
                    if text in REFUSALS:
                        break           # it heard something else: ask again now
            except serial.SerialTimeoutException as err:
                raise SerialTimeout("Khepera on %s: could not write %r within %.2f s: %s"
                                    % (self.port, what, self.timeout, err)) from err
            except PORT_ERRORS as err:
                self._drop()
                raise SerialPortLost("Khepera on %s: port failed during %r: %s"
                                     % (self.port, what, err)) from err
        tries = self.retries + 1
        heard = [t for t in seen if t]
        if not heard:
            raise SerialTimeout("Khepera on %s did not answer %r within %.2f s (%d tries); "
                                "is it on and in mode at %d baud?"
                                % (self.port, what, self.timeout, tries, self.baud))
        refused = [t for t in heard if t in REFUSALS]
        if refused:
            raise ProtocolError("Khepera on %s answered %r to %r on all %d tries"
                                % (self.port, refused[-1].decode(), what, tries))
        raise ProtocolError("Khepera on %s: no valid reply to %r in %d tries (got %r); check "
                            "the baud rate (the mode jumper sets one of %s)"
                            % (self.port, what, tries, heard[-1][:40],
                               ", ".join(map(str, BAUDS))))

    def command(self, letter: str, *args: int, count: int | None = None) -> list[int]:
        """Send one command; return the reply's values (`count` ints if given)."""
        def ints(fields: list[bytes]) -> list[int] | None:
            try:
                v = [int(f) for f in fields]
            except ValueError:
                return None             # garbled digits: another line or a retry
            return v if count is None or len(v) == count else None
        return self._exchange(letter, args, ints)

    def version(self) -> tuple[str, str]:
        """(BIOS, protocol) versions from `B`; ProtocolError if not a Khepera."""
        def banner(fields: list[bytes]) -> tuple[str, str] | None:
            if len(fields) != 2:
                return None
            return (fields[0].decode("ascii", "replace"),
                    fields[1].decode("ascii", "replace"))
        return self._exchange("B", (), banner)

    def set_speed(self, left: int, right: int) -> None:
        self.command("D", max(-127, min(127, left)), max(-127, min(127, right)), count=0)

    def counters(self) -> tuple[int, int]:
        v = self.command("H", count=2)
        return v[0], v[1]

    def reset_counters(self) -> None:
        self.command("G", 0, 0, count=0)

    def proximity(self) -> list[int]:
        return self.command("N", count=8)

    def ambient(self) -> list[int]:
        return self.command("O", count=8)

    def led(self, n: int, act: int) -> None:
        self.command("L", n, act, count=0)


def _nearest(bearing: float) -> tuple[int, float]:
    best, dist = 0, 999.0
    for k, b in enumerate(PROX_BEARINGS):
        d = abs((bearing - b + 180) % 360 - 180)
        if d < dist:
            best, dist = k, d
    return best, dist


def _angle(a: float) -> float:
    """Into -180..180."""
    return (a + 180) % 360 - 180


class KheperaBody(HostBody):
    """The firmware HAL over a Khepera II (the firmware runs on the host).

    `link` carries the robot's messages (robot_send / robot_recv, as the sim
    engine's links do). Positions are reported in Q8 patches of `patch_mm`.
    `tick_s` is the runner's tick period: each tick the speeds are set to
    cover half the rest of the move by the next tick, never faster than
    `cruise` (pulses / 10 ms).
    A turn ends within `turn_tolerance` degrees; a phase still unfinished
    after `move_ticks` ticks (a stalled wheel) is stopped and abandoned.
    """

    def __init__(self, robot: KheperaII, node: int, link: object | None = None,
                 patch_mm: float = 50.0, touch_threshold: int = 600, dark: int = 450,
                 light_step: int = 40, cruise: int = 20, x_mm: float = 0.0,
                 y_mm: float = 0.0, heading: float = 0.0, tick_s: float = 0.05,
                 move_ticks: int = 200, turn_tolerance: float = 2.0,
                 clock: Clock | None = None) -> None:
        super().__init__(node, link, patch_mm, x_mm, y_mm, heading, clock)
        self.k = robot
        self.touch_threshold = touch_threshold
        self.dark = dark
        self.light_step = light_step
        self.cruise = cruise
        self.tick_s = tick_s
        self.move_ticks = move_ticks
        self.turn_tolerance = turn_tolerance
        self.speed = (0, 0)             # what the wheels were last told
        bios, proto = robot.version()
        log.info("Khepera II BIOS %s protocol %s", bios, proto)
        robot.set_speed(0, 0)
        self.last = robot.counters()

    # -- odometry -------------------------------------------------------------------

    def update(self) -> None:
        """Read the counters and integrate the pose (one `H` round trip)."""
        left, right = self.k.counters()
        dl = (left - self.last[0]) * PULSE_MM
        dr = (right - self.last[1]) * PULSE_MM
        self.last = (left, right)
        dth = math.degrees((dl - dr) / WHEEL_BASE_MM)
        mid = math.radians(self.theta + dth / 2)
        d = (dl + dr) / 2
        self.x_mm += d * math.sin(mid)
        self.y_mm += d * math.cos(mid)
        self.theta = (self.theta + dth) % 360

    def _refresh_pose(self) -> None:
        self._reading("H", self.update)

    # -- motion, one step per tick -----------------------------------------------------------

    def _speed_for(self, wheel_mm: float) -> int:
        """Pulses / 10 ms that cover half of `wheel_mm` in one tick, 1..cruise.
        Half: a tick that runs long (a loaded host) overshoots by less than
        the error it corrects, so the steering converges up to ticks 4x
        longer than `tick_s` instead of oscillating at 2x."""
        per_tick = self.tick_s / SPEED_PERIOD_S
        pulses = wheel_mm / PULSE_MM / APPROACH_TICKS
        return max(1, min(self.cruise, int(round(pulses / per_tick))))

    def _steer(self, ph: Phase) -> tuple[int, int] | None:
        """The speeds for this phase now, or None when it is done."""
        if ph.kind == TURN:
            err = _angle(ph.heading - self.theta)
            if abs(err) < self.turn_tolerance:
                return None
            s = self._speed_for(math.radians(abs(err)) * WHEEL_BASE_MM / 2)
            return (s, -s) if err > 0 else (-s, s)
        done = math.hypot(self.x_mm - ph.x0, self.y_mm - ph.y0)
        if done >= ph.mm - 0.5:
            return None
        s = self._speed_for(ph.mm - done)
        return s, s

    def _set(self, speed: tuple[int, int]) -> None:
        if speed != self.speed:
            self.k.set_speed(*speed)
            self.speed = speed

    def _advance(self) -> None:
        self._refresh_pose()
        while self.phases:
            ph = self.phases[0]
            if ph.ticks == 0:
                ph.x0, ph.y0 = self.x_mm, self.y_mm
            speed = self._steer(ph)
            if speed is None:
                self.phases.pop(0)
                continue
            if ph.ticks >= self.move_ticks:
                log.warning("Khepera body %d: %r unfinished after %d ticks; abandoned",
                            self.node, ph, ph.ticks)
                self.abandoned += 1
                self.phases.clear()
                break
            ph.ticks += 1
            self._set(speed)
            return
        self._set((0, 0))

    _begin = _advance

    def turn_to(self, heading: float) -> None:
        """Start turning in place to `heading` (degrees); see begin_tick()."""
        self._start([Phase(TURN, heading=heading % 360)])

    def drive(self, mm: float) -> None:
        """Start driving `mm` straight ahead; see begin_tick()."""
        self._start([Phase(DRIVE, mm=mm)] if mm > 0 else [])

    # -- sensing ---------------------------------------------------------------------

    # x() / y(): HostBody

    def _rel(self, heading: int) -> float:
        self._refresh_pose()
        return _angle(heading - self.theta)

    def _proximity(self) -> list[int]:
        return self._reading("N", self.k.proximity)      # type: ignore[return-value]

    def _ambient(self) -> list[int]:
        return self._reading("O", self.k.ambient)        # type: ignore[return-value]

    def probe(self, heading: int) -> int:
        k, dist = _nearest(self._rel(heading))
        if dist > 50:
            return NOTHING
        return OBJECT if self._proximity()[k] >= self.touch_threshold else NOTHING

    def _field_from(self, v: int) -> int:
        return max(0, self.dark - v) // self.light_step

    def field_ahead(self, heading: int) -> int:
        k, _ = _nearest(self._rel(heading))
        return self._field_from(self._ambient()[k])

    def field_here(self) -> int:
        return min(self._field_from(v) for v in self._ambient())

    def uphill(self) -> int:
        amb = self._ambient()
        self._refresh_pose()
        k = min(range(8), key=lambda i: amb[i])
        if self._field_from(amb[k]) <= min(self._field_from(v) for v in amb):
            return -1
        return int(round(((self.theta + PROX_BEARINGS[k]) % 360) / 45.0)) * 45 % 360

    def holding(self) -> int:
        if self.claimed < 0:
            return 0
        return 1 if self.probe(self.claimed) == OBJECT else 0

    # -- acting -------------------------------------------------------------------------

    def forward(self, heading: int, step: int) -> None:
        self._start([Phase(TURN, heading=heading % 360),
                     Phase(DRIVE, mm=step * self.patch_mm / fx.ONE)])

    def claim(self, heading: int) -> None:
        self.claimed = heading
        self._start([Phase(TURN, heading=heading % 360)])

    def carry(self, dx: int, dy: int) -> None:
        if dx == 0 and dy == 0:
            return
        h = math.degrees(math.atan2(dx, dy)) % 360
        self._start([Phase(TURN, heading=h), Phase(DRIVE, mm=math.hypot(dx, dy) * self.patch_mm)])

    def beacon(self, on: int) -> None:
        self.k.led(0, 1 if on else 0)
        self.beacon_on = 1 if on else 0

    # -- messages --------------------------------------------------------------------------

    # send / recv: HostBody
