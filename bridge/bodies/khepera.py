"""khepera://PORT: a Khepera II whose firmware runs on the host (KheperaBody)."""

from __future__ import annotations

from bridge.bodies import BodyContext, BodySpec, Opened, open_host_body, start_pose

TUNING = ("cruise", "touch_threshold", "dark", "light_step")


def open_body(spec: BodySpec, ctx: BodyContext) -> Opened:
    from bridge.serial.khepera import KheperaBody, KheperaII
    pose = start_pose(spec, ctx)
    baud = int(spec.get("baud", 38400))
    tuning = {k: spec.options[k] for k in TUNING if k in spec.options}

    def stop(k: KheperaII, body: KheperaBody) -> None:
        k.set_speed(0, 0)
        k.led(0, 0)

    # the body's constructor asks the robot its version and stops the
    # wheels: a robot that does not answer is refused before the mission
    return open_host_body(
        spec, lambda: KheperaII(spec.port, baud, timeout=0.5),
        lambda k: KheperaBody(k, ctx.node, link=ctx.link, tick_s=ctx.tick_s, clock=ctx.clock,
                              **pose, **tuning),
        stop, f"Khepera II on {spec.port} at {baud} baud")
