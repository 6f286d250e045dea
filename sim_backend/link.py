"""The link contract, once for the engines and the host process: how robot
messages travel between the robots and the host coordinator.

A link has two ends. The robots' end (`robot_send`, `robot_recv`) is what a
robot's body uses inside an engine. The host's end (`HostEnd`) is what the
host coordinator's driver uses: messages in, messages out, dropped frames
counted, the port closed. The engine's in-process links (`Link`: InprocLink,
the CAN link, the recorder) carry both ends in one process and are read at
the tick boundary, so their host end takes no deadline: `host_recv()` is a
`poll(0)` and `host_send` a `send`. The host process's transports (CAN bus,
serial ports, bridge/transport.py) carry the host's end only.
"""

from __future__ import annotations

from typing import Protocol

Message = tuple[int, int, tuple]   # (node, kind, fields) as in firmware_logic.messages


class HostEnd(Protocol):
    """The host's end of a link as the host process drives it."""

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


class Link(RobotEnd, Protocol):
    """A link inside an engine: both ends in one process, the host's read at
    the tick boundary (host_recv: everything the robots sent this tick)."""

    def host_recv(self) -> list[Message]: ...

    def host_send(self, node: int, kind: int, fields: tuple) -> None: ...
