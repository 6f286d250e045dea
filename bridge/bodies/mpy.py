"""mpy://PORT: a MicroPython robot running its own firmware (deployed with
`touchswarm deploy`, started with --start); the host serves its SENSOR and
ACTION frames from the sim world (sim_backend/emulators/tether.py), so the
board, its firmware and the link are real and its body is simulated."""

from __future__ import annotations

from bridge.bodies import BodyContext, BodySpec, BodyURLError, Opened
from bridge.serial.errors import SerialLinkError


def open_body(spec: BodySpec, ctx: BodyContext) -> Opened:
    from bridge.serial.transport import DEFAULT_BAUD, SerialTransport
    baud = int(spec.get("baud", DEFAULT_BAUD))
    try:
        # short poll timeout: the mission polls once per tick
        t = SerialTransport(spec.port, baud, timeout=0.01, reopen_every=0.05)
    except SerialLinkError as err:
        raise BodyURLError(f"body {spec.url!r}: {err}") from err
    return Opened("tether", spec, transport=t, closers=[t.close],
                  text=f"MicroPython robot on {spec.port} at {baud} baud")
