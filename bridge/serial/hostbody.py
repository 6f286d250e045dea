"""What the host-side robot bodies (Khepera II, GoGo) share: a pose kept in
millimetres and reported to the firmware in Q8 patches, and messaging over
an engine Link (sim_backend.engine.Link) or nowhere."""

from __future__ import annotations

from firmware_logic import fixedpoint as fx
from firmware_logic import messages as msg
from firmware_logic.hal import Hal


class HostBody(Hal):
    """Base of a HAL driven from the host; subclasses set node, link,
    patch_mm, x_mm and y_mm and implement the sensing and acting calls."""

    node: int
    link: object | None
    patch_mm: float
    x_mm: float
    y_mm: float

    def _q8(self, mm: float) -> int:
        return int(round(mm * fx.ONE / self.patch_mm))

    def x(self) -> int:
        return self._q8(self.x_mm)

    def y(self) -> int:
        return self._q8(self.y_mm)

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
