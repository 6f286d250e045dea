"""sim://: the node keeps its simulated body (the engine's SimBody)."""

from __future__ import annotations

from bridge.bodies import BodyContext, BodySpec, Opened


def open_body(spec: BodySpec, ctx: BodyContext) -> Opened:
    return Opened("sim", spec, text="simulated")
