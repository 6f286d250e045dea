"""A hand-driven HAL for unit tests of single FSM rules."""

from firmware_logic.behaviours.thesis.robot import NOTHING


class FakeHal:
    def __init__(self):
        self.px = 0
        self.py = 0
        self.probes = {}          # heading -> result (default NOTHING)
        self.probe_default = NOTHING
        self.ahead_field = 0
        self.up = -1
        self.held = 1
        self.inbox = []
        self.log = []             # (call, args...) in order
        self.sent = []

    def x(self):
        return self.px

    def y(self):
        return self.py

    def probe(self, h):
        self.log.append(("probe", h))
        return self.probes.get(h, self.probe_default)

    def field_ahead(self, h):
        self.log.append(("field_ahead", h))
        return self.ahead_field

    def field_here(self):
        return 0

    def uphill(self):
        self.log.append(("uphill",))
        return self.up

    def holding(self):
        return self.held

    def forward(self, h, step):
        self.log.append(("forward", h, step))

    def claim(self, h):
        self.log.append(("claim", h))

    def carry(self, dx, dy):
        self.log.append(("carry", dx, dy))

    def beacon(self, on):
        self.log.append(("beacon", on))

    def send(self, kind, *a):
        self.sent.append((kind,) + a)

    def recv(self, buf):
        if not self.inbox:
            return 0
        kind, fields = self.inbox.pop(0)
        for i, v in enumerate(fields):
            buf[i] = v
        return kind

    def calls(self, name):
        return [c for c in self.log if c[0] == name]
