"""A Khepera II in remote-control mode, on a pty, backed by the sim world.

Written from the protocol description (docs/serial.md, protocols.md) on its
own: it shares no code with bridge/serial/khepera.py, so a bug in one shows
up against the other.

Serial: 8 data bits, 2 stop bits (11 bits a byte on the wire), replies
delayed by (request + reply bytes) x 11 / baud. A host at another baud
rate gets garbage, as from a real UART. Commands: B, D, E, G, H, L, N, O
(others answer `Command not found`; a wrong argument count answers
`z,Protocol error`, as KiKS does).

Strict on purpose, so a lenient driver shows up here rather than on a
robot: a line longer than MAX_LINE bytes is discarded up to its CR and
answered `z,Protocol error` as a whole (no tail of it is ever executed);
arguments must be plain decimal integers (`-12`, not ` 12`, `+12` or
`1_2`); a command letter is one upper-case letter with nothing around it.

The body: one robot of a sim World (index `index`), pose kept in mm and
degrees (0 = north, clockwise) and mirrored into the world's Q8 position.
Wheels move by the set speeds (pulses per 10 ms) in the time of `clock`
(wall time by default; a SimClock for tests that must not depend on load).
Proximity sensor k reads high (about 1000) when the patch one patch away
in its direction is object, wall or robot, else a low noise level; ambient
sensor k reads `dark - field x light_step` of the patch in its direction
(lower is brighter). LED 0 is the beacon: on adds the robot's field to the
world (Signal), off removes it.
"""

from __future__ import annotations

import re

from sim_backend.emulators.ptyport import Emulator
from sim_backend.emulators.worldrobot import SimClock, SystemClock, WorldRobot
from sim_backend.world import FREE

BANNER = b"\r\nKhepera II BIOS rev 5.01\r\nSerial Communication Protocol\r\n"
PULSE_MM = 1.0 / 12.0
WHEEL_BASE_MM = 53.0
# sensor bearings relative to the robot's heading, clockwise degrees
# (0 left side ... 5 right side, 6 rear right, 7 rear left)
SENSOR_BEARINGS = (-90, -45, -10, 10, 45, 90, 170, -170)
MAX_LINE = 64                           # no command is that long
INTEGER = re.compile(rb"-?[0-9]+\Z")


class KheperaEmulator(WorldRobot, Emulator):
    bits_per_byte = 11

    def __init__(self, world=None, index: int = 0, baud: int = 38400,
                 patch_mm: float = 50.0, heading: float = 0.0, path: str | None = None,
                 dark: int = 450, light_step: int = 40,
                 clock: SimClock | SystemClock | None = None) -> None:
        super().__init__(baud, path)
        self.clock = clock if clock is not None else SystemClock()
        self.world = world
        self.index = index
        self.patch_mm = patch_mm
        self.dark = dark
        self.light_step = light_step
        if world is not None:
            self.x_mm = world.xs[index] * patch_mm / 256.0
            self.y_mm = world.ys[index] * patch_mm / 256.0
        else:
            self.x_mm = self.y_mm = 0.0
        self.theta = heading
        self.pos = [0.0, 0.0]           # encoder counters (float, reported as int)
        self.speed = [0, 0]
        self.leds = [0, 0]
        self.beacon_src: tuple[int, int] | None = None
        self._t = self.clock.now()
        self._line = b""
        self._overlong = False          # discarding the rest of a line too long
        self.commands = 0
        self.refused = 0                # lines answered with an error
        # faults for tests
        self.garbage_next = b""         # sent before the next reply
        self.truncate_next = 0          # cut the next reply to this many bytes
        self.mute_next = 0              # do not answer the next N requests
        self.corrupt_request_next = 0   # noise hits the next N requests on their way in
        self.reply(BANNER)

    # -- physics ---------------------------------------------------------------

    def _integrate(self) -> None:
        now = self.clock.now()
        dt = now - self._t
        self._t = now
        if dt <= 0 or self.speed == [0, 0]:
            return
        dl = self.speed[0] * dt / 0.01
        dr = self.speed[1] * dt / 0.01
        self.pos[0] += dl
        self.pos[1] += dr
        self._drive(dl * PULSE_MM, dr * PULSE_MM, WHEEL_BASE_MM)

    def proximity(self) -> list[int]:
        out = []
        for k, b in enumerate(SENSOR_BEARINGS):
            v = 8 + (k * 3) % 7
            if self.world is not None:
                w = self.world
                p = self._look(b)
                if not w.inside(*p):
                    v = 1000
                else:
                    i = w.idx(*p)
                    here = self._patch(self.x_mm, self.y_mm)
                    if w.obj[i] != FREE or (w.occ[i] > 0 and p != here):
                        v = 1000 + k
            out.append(min(v, 1023))
        return out

    def ambient(self) -> list[int]:
        out = []
        for b in SENSOR_BEARINGS:
            f = 0
            if self.world is not None:
                p = self._look(b)
                if self.world.inside(*p):
                    f = self.world.field[self.world.idx(*p)]
            out.append(max(0, min(1023, self.dark - f * self.light_step)))
        return out

    # -- protocol ----------------------------------------------------------------

    def on_bytes(self, data: bytes) -> None:
        for c in data:
            if c in (10, 13):
                line, self._line = self._line, b""
                if self._overlong:
                    self._overlong = False
                    self._refuse("z,Protocol error", MAX_LINE + 1)
                elif line:
                    self._command(line)
            elif self._overlong:
                continue
            else:
                self._line += bytes([c])
                if len(self._line) > MAX_LINE:
                    # the whole line is bad: drop it up to its CR, then say so
                    self._line = b""
                    self._overlong = True

    def _send(self, text: str, request_len: int) -> None:
        out = self.garbage_next + text.encode("ascii") + b"\r\n"
        self.garbage_next = b""
        if self.truncate_next:
            out = out[: self.truncate_next]
            self.truncate_next = 0
        self.reply(out, request_len)

    def _refuse(self, text: str, request_len: int) -> None:
        self.refused += 1
        self._send(text, request_len)

    def _command(self, line: bytes) -> None:
        self.commands += 1
        if self.mute_next:
            self.mute_next -= 1
            return
        if self.corrupt_request_next:
            self.corrupt_request_next -= 1
            line = b"\xf3" + line[1:]          # the command letter hit by noise
        parts = line.split(b",")
        cmd = parts[0].decode("latin-1")
        need = {"B": 0, "D": 2, "E": 0, "G": 2, "H": 0, "L": 2, "N": 0, "O": 0}
        if cmd not in need:
            self._refuse("Command not found", len(line) + 1)
            return
        if not all(INTEGER.match(a) for a in parts[1:]) or len(parts) - 1 != need[cmd]:
            self._refuse("z,Protocol error", len(line) + 1)
            return
        args = [int(a) for a in parts[1:]]
        self._integrate()
        low = cmd.lower()
        if cmd == "B":
            reply = "b,5.01,5.00"
        elif cmd == "D":
            self.speed = [max(-127, min(127, args[0])), max(-127, min(127, args[1]))]
            reply = low
        elif cmd == "E":
            reply = "e,%d,%d" % tuple(self.speed)
        elif cmd == "G":
            self.pos = [float(args[0]), float(args[1])]
            reply = low
        elif cmd == "H":
            reply = "h,%d,%d" % (int(self.pos[0]), int(self.pos[1]))
        elif cmd == "L":
            n, act = args
            if n in (0, 1) and act in (0, 1, 2):
                self.leds[n] = (1 - self.leds[n]) if act == 2 else act
                if n == 0:
                    self._beacon(self.leds[0])
            reply = low
        elif cmd == "N":
            reply = "n," + ",".join(str(v) for v in self.proximity())
        else:
            reply = "o," + ",".join(str(v) for v in self.ambient())
        self._send(reply, len(line) + 1)

