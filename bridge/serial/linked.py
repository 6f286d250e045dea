"""Messaging for host-side robot bodies (Khepera II, GoGo): the firmware's
send/recv go to an engine Link (sim_backend.engine.Link) or nowhere."""

from __future__ import annotations

from firmware_logic import messages as msg
from firmware_logic.hal import Hal


class LinkedHal(Hal):
    """A HAL whose messages travel over `self.link` as node `self.node`."""

    node: int
    link: object | None

    def send(self, kind: int, a0: int, a1: int, a2: int, a3: int, a4: int, a5: int) -> None:
        if self.link is not None:
            n = len(msg.fields(kind))
            self.link.robot_send(self.node, kind, (a0, a1, a2, a3, a4, a5)[:n])

    def recv(self, buf: list) -> int:
        if self.link is None:
            return 0
        m = self.link.robot_recv(self.node)
        if m is None:
            return 0
        kind, fields = m
        for j, v in enumerate(fields):
            buf[j] = v
        return kind
