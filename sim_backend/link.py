"""The link contract, once for the engines and the host process: how robot
messages travel between the robots and the host coordinator.

A link has two ends. The robots' end (`robot_send`, `robot_recv`) is what a
robot's body uses inside an engine. The host's end (`HostEnd`) is what every
host coordinator's driver uses, in an engine or in the host process: messages
in (`poll`), messages out (`send`), dropped frames counted, the port closed.
The host process's transports (CAN bus, serial ports, bridge/transport.py)
carry the host's end only and wait up to the poll's deadline for frames. An
engine's links (`Link`: InprocLink, the CAN link, the recorder, the mixed
mission's) carry both ends in one process; the engine polls once per tick,
at the tick boundary, with no deadline (`poll(0)`): what the robots sent
this tick.
"""

from __future__ import annotations

from typing import Protocol

Message = tuple[int, int, tuple]   # (node, kind, fields) as in firmware_logic.messages


class HostEnd(Protocol):
    """The host's end of a link, as the host process and the engines drive it."""

    def poll(self, timeout: float) -> list[Message]:
        """Messages received within `timeout` seconds (may be empty); returns by
        then even when more keep coming (the rest wait for the next poll)."""

    def send(self, node: int, kind: int, fields: tuple) -> None:
        """Send one message to `node` (0: every robot on this transport)."""

    def bad_frames(self) -> dict[str, int]:
        """Dropped frames so far, by kind of fault."""

    def close(self) -> None:
        """Release the port or bus; safe to call twice; never raises (a lost
        link fails to close as well, and must not mask why it was lost)."""


class RobotEnd(Protocol):
    """The robots' end of a link, as a robot's body inside an engine uses it."""

    def robot_send(self, node: int, kind: int, fields: tuple) -> None: ...

    def robot_recv(self, node: int) -> tuple[int, tuple] | None: ...


class Link(RobotEnd, HostEnd, Protocol):
    """A link inside an engine: both ends in one process. The engine polls the
    host's end once per tick with `poll(0)` (everything the robots sent this
    tick; an engine link may count its ticks by these polls) and `send`s the
    coordinator's commands, which reach the robots before their next tick."""
