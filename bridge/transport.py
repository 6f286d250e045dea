"""Transports joined for the host process.

A CAN bus (bridge/links), a serial port with framed messages (bridge/serial)
or the in-process link all look the same to the host: the host's end of a
link (sim_backend/link.py HostEnd), decoded messages in, messages out. Bad
frames never reach the host: a transport counts them by kind, logs each
kind once, and drops them.
"""

from __future__ import annotations

import logging
from typing import Sequence

from bridge.errors import BridgeError
from sim_backend.link import HostEnd, Message

log = logging.getLogger(__name__)


class FanIn:
    """Several transports as one: a message to a node goes to the transport
    that node was heard on (node 0, or a node never heard: every transport).
    Lets one host serve robots on a CAN bus and on serial ports at once."""

    def __init__(self, parts: Sequence[HostEnd]) -> None:
        self.parts = list(parts)
        self.heard_on: dict[int, HostEnd] = {}

    def __enter__(self) -> "FanIn":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def poll(self, timeout: float) -> list[Message]:
        out: list[Message] = []
        # each part gets its share of the deadline (a zero share would give a
        # busy part one frame per poll and starve it behind the others)
        share = timeout / max(1, len(self.parts))
        for part in self.parts:
            got = part.poll(share)
            for m in got:
                self.heard_on[m[0]] = part
            out.extend(got)
        return out

    def send(self, node: int, kind: int, fields: tuple) -> None:
        part = self.heard_on.get(node) if node else None
        for p in (part,) if part is not None else self.parts:
            p.send(node, kind, fields)

    def bad_frames(self) -> dict[str, int]:
        out: dict[str, int] = {}
        for part in self.parts:
            for k, v in part.bad_frames().items():
                out[k] = out.get(k, 0) + v
        return out

    def close(self) -> None:
        for part in self.parts:
            try:
                part.close()
            except (BridgeError, OSError) as err:   # close the others all the same
                log.warning("closing %r failed: %s", part, err)
