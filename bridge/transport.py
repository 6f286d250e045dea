"""What the host process needs from anything that carries robot messages.

A CAN bus (bridge/links), a serial port with framed messages (bridge/serial)
or the in-process link all look the same to the host: decoded messages in,
messages out. Bad frames never reach the host: a transport counts them by
kind, logs each kind once, and drops them.
"""

from __future__ import annotations

from typing import Protocol

Message = tuple[int, int, tuple]   # (node, kind, fields) as in firmware_logic.messages


class RobotTransport(Protocol):
    def poll(self, timeout: float) -> list[Message]:
        """Messages received within `timeout` seconds (may be empty)."""

    def send(self, node: int, kind: int, fields: tuple) -> None:
        """Send one message to `node` (0: every robot on this transport)."""

    def bad_frames(self) -> dict[str, int]:
        """Dropped frames so far, by kind of fault."""

    def close(self) -> None:
        """Release the port or bus; safe to call twice."""
