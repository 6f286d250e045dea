"""Khepera II over its RS-232 ASCII protocol, and a firmware HAL on top.

`KheperaII` is the protocol client: one upper-case command letter with
comma-separated arguments and CR; the reply is the lower-case letter with
values, CR LF. Every read has a deadline; stale input is flushed before each
command; a garbled, truncated or missing reply is retried `retries` times
and then raises ProtocolError / SerialTimeout naming the command (and, when
nothing sensible ever came back, suggesting the baud rate, which on a
Khepera II is set by its mode jumper).

`KheperaBody` is the HAL of firmware_logic/hal.py for a Khepera II whose
firmware runs on the host (the "remote brain" of the thesis's hardware
option): odometry from the `H` counters (1 pulse = 1/12 mm, wheel base
53 mm) gives the pose; proximity `N` above `touch_threshold` in a direction
is a touch (the object); ambient light `O` gives the field (a lit beacon LED,
`L`, is a stationary robot's field source); `D` drives the wheels.
"""

from __future__ import annotations

import logging
import math
import time
from types import TracebackType

import serial

from bridge.serial.errors import ProtocolError, SerialTimeout
from bridge.serial.transport import open_serial, resolve_url
from firmware_logic import fixedpoint as fx
from bridge.serial.hostbody import HostBody
from firmware_logic.behaviours.thesis.robot import NOTHING, OBJECT

log = logging.getLogger(__name__)

PULSE_MM = 1.0 / 12.0
WHEEL_BASE_MM = 53.0
# sensor bearings relative to the heading, clockwise degrees (0 = left side)
PROX_BEARINGS = (-90, -45, -10, 10, 45, 90, 170, -170)
BAUDS = (9600, 19200, 38400, 57600, 115200)


class KheperaII:
    def __init__(self, url: str, baud: int = 38400, timeout: float = 0.5,
                 retries: int = 2) -> None:
        port, opts = resolve_url(url, "khepera", 38400)
        self.port = port
        self.baud = int(opts.get("baud", baud))
        self.timeout = timeout
        self.retries = retries
        self.ser = open_serial(port, self.baud, 0.02, stopbits=serial.STOPBITS_TWO)
        self.retried = 0

    def __enter__(self) -> "KheperaII":
        return self

    def __exit__(self, et: type[BaseException] | None, ev: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()

    def close(self) -> None:
        ser, self.ser = self.ser, None
        if ser is not None:
            try:
                ser.close()
            except (serial.SerialException, OSError):
                pass

    def _readline(self, deadline: float) -> bytes | None:
        buf = b""
        while time.monotonic() < deadline:
            chunk = self.ser.read(1)
            if not chunk:
                continue
            buf += chunk
            if buf.endswith(b"\n"):
                return buf
            if len(buf) > 200:
                return buf
        return None

    def command(self, letter: str, *args: int) -> list[int]:
        """Send one command; return the reply's values (ints)."""
        if self.ser is None:
            raise ProtocolError("Khepera on %s: port is closed" % self.port)
        req = (",".join([letter] + [str(int(a)) for a in args]) + "\r").encode("ascii")
        want = letter.lower().encode("ascii")
        seen: list[bytes] = []
        for attempt in range(self.retries + 1):
            if attempt:
                self.retried += 1
            try:
                self.ser.reset_input_buffer()
                self.ser.write(req)
                deadline = time.monotonic() + self.timeout
                while True:
                    line = self._readline(deadline)
                    if line is None:
                        break
                    text = line.strip()
                    seen.append(text)
                    if text == want or text.startswith(want + b","):
                        try:
                            return [int(v) for v in text.split(b",")[1:]]
                        except ValueError:
                            continue     # garbled digits: wait for another line / retry
                    if text in (b"Command not found", b"z,Protocol error"):
                        raise ProtocolError("Khepera on %s answered %r to %r"
                                            % (self.port, text.decode(), req.decode().strip()))
            except (serial.SerialException, OSError) as err:
                raise SerialTimeout("Khepera on %s: port failed during %r: %s"
                                    % (self.port, req.decode().strip(), err)) from err
        if not any(seen):
            raise SerialTimeout("Khepera on %s did not answer %r within %.2f s (%d tries); "
                                "is it on and in mode at %d baud?"
                                % (self.port, req.decode().strip(), self.timeout,
                                   self.retries + 1, self.baud))
        raise ProtocolError("Khepera on %s: no valid reply to %r in %d tries (got %r); check "
                            "the baud rate (the mode jumper sets one of %s)"
                            % (self.port, req.decode().strip(), self.retries + 1, seen[-1][:40],
                               ", ".join(map(str, BAUDS))))

    def version(self) -> tuple[str, str]:
        """(BIOS, protocol) versions from `B`; ProtocolError if not a Khepera."""
        req = b"B\r"
        for _ in range(self.retries + 1):
            self.ser.reset_input_buffer()
            self.ser.write(req)
            deadline = time.monotonic() + self.timeout
            while True:
                line = self._readline(deadline)
                if line is None:
                    break
                parts = line.strip().split(b",")
                if parts[0] == b"b" and len(parts) == 3:
                    return parts[1].decode("ascii", "replace"), parts[2].decode("ascii",
                                                                               "replace")
        raise ProtocolError("no Khepera banner/version on %s at %d baud (B gave nothing "
                            "valid); check the port and the baud rate (one of %s)"
                            % (self.port, self.baud, ", ".join(map(str, BAUDS))))

    def set_speed(self, left: int, right: int) -> None:
        self.command("D", max(-127, min(127, left)), max(-127, min(127, right)))

    def counters(self) -> tuple[int, int]:
        v = self.command("H")
        if len(v) != 2:
            raise ProtocolError("H: expected 2 counters, got %r" % v)
        return v[0], v[1]

    def reset_counters(self) -> None:
        self.command("G", 0, 0)

    def proximity(self) -> list[int]:
        v = self.command("N")
        if len(v) != 8:
            raise ProtocolError("N: expected 8 proximity values, got %d" % len(v))
        return v

    def ambient(self) -> list[int]:
        v = self.command("O")
        if len(v) != 8:
            raise ProtocolError("O: expected 8 ambient values, got %d" % len(v))
        return v

    def led(self, n: int, act: int) -> None:
        self.command("L", n, act)


def _nearest(bearing: float) -> tuple[int, float]:
    best, dist = 0, 999.0
    for k, b in enumerate(PROX_BEARINGS):
        d = abs((bearing - b + 180) % 360 - 180)
        if d < dist:
            best, dist = k, d
    return best, dist


class KheperaBody(HostBody):
    """The firmware HAL over a Khepera II (the firmware runs on the host).

    `link` carries the robot's messages (robot_send / robot_recv, as the sim
    engine's links do). Positions are reported in Q8 patches of `patch_mm`.
    """

    def __init__(self, robot: KheperaII, node: int, link=None, patch_mm: float = 50.0,
                 touch_threshold: int = 600, dark: int = 450, light_step: int = 40,
                 cruise: int = 20, x_mm: float = 0.0, y_mm: float = 0.0,
                 heading: float = 0.0, move_timeout: float = 10.0) -> None:
        self.k = robot
        self.node = node
        self.link = link
        self.patch_mm = patch_mm
        self.touch_threshold = touch_threshold
        self.dark = dark
        self.light_step = light_step
        self.cruise = cruise
        self.move_timeout = move_timeout
        self.x_mm, self.y_mm, self.theta = x_mm, y_mm, heading
        self.claimed = -1
        self.beacon_on = 0
        bios, proto = robot.version()
        log.info("Khepera II BIOS %s protocol %s", bios, proto)
        robot.set_speed(0, 0)
        self.last = robot.counters()

    # -- odometry -------------------------------------------------------------------

    def update(self) -> None:
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

    # -- sensing ---------------------------------------------------------------------

    # x() / y(): HostBody

    def _rel(self, heading: int) -> float:
        return (heading - self.theta + 180) % 360 - 180

    def probe(self, heading: int) -> int:
        k, dist = _nearest(self._rel(heading))
        if dist > 50:
            return NOTHING
        return OBJECT if self.k.proximity()[k] >= self.touch_threshold else NOTHING

    def _field_from(self, v: int) -> int:
        return max(0, self.dark - v) // self.light_step

    def field_ahead(self, heading: int) -> int:
        k, _ = _nearest(self._rel(heading))
        return self._field_from(self.k.ambient()[k])

    def field_here(self) -> int:
        return min(self._field_from(v) for v in self.k.ambient())

    def uphill(self) -> int:
        amb = self.k.ambient()
        k = min(range(8), key=lambda i: amb[i])
        if self._field_from(amb[k]) <= min(self._field_from(v) for v in amb):
            return -1
        return int(round(((self.theta + PROX_BEARINGS[k]) % 360) / 45.0)) * 45 % 360

    def holding(self) -> int:
        if self.claimed < 0:
            return 0
        return 1 if self.probe(self.claimed) == OBJECT else 0

    # -- acting -------------------------------------------------------------------------

    def turn_to(self, heading: float) -> None:
        end = time.monotonic() + self.move_timeout
        try:
            while True:
                self.update()
                err = (heading - self.theta + 180) % 360 - 180
                if abs(err) < 4 or time.monotonic() > end:
                    break
                s = max(2, min(self.cruise, int(abs(err) / 3)))
                self.k.set_speed(s if err > 0 else -s, -s if err > 0 else s)
        finally:
            self.k.set_speed(0, 0)
        self.update()

    def drive(self, mm: float) -> None:
        end = time.monotonic() + self.move_timeout
        x0, y0 = self.x_mm, self.y_mm
        try:
            while True:
                self.update()
                done = math.hypot(self.x_mm - x0, self.y_mm - y0)
                if done >= mm - 0.5 or time.monotonic() > end:
                    break
                s = max(2, min(self.cruise, int((mm - done) / 2)))
                self.k.set_speed(s, s)
        finally:
            self.k.set_speed(0, 0)
        self.update()

    def forward(self, heading: int, step: int) -> None:
        self.turn_to(heading)
        self.drive(step * self.patch_mm / fx.ONE)

    def claim(self, heading: int) -> None:
        self.turn_to(heading)
        self.claimed = heading

    def carry(self, dx: int, dy: int) -> None:
        h = math.degrees(math.atan2(dx, dy)) % 360
        self.turn_to(h)
        self.drive(math.hypot(dx, dy) * self.patch_mm)

    def beacon(self, on: int) -> None:
        self.k.led(0, 1 if on else 0)
        self.beacon_on = on

    # -- messages --------------------------------------------------------------------------

    # send / recv: HostBody
