"""gogo://PORT: a GoGo Board robot whose firmware runs on the host (GoGoBody)."""

from __future__ import annotations

from bridge.bodies import BodyContext, BodySpec, Opened, open_host_body, start_pose

TUNING = ("mm_s_per_level", "wheel_base_mm", "power", "dark", "light_step", "touch_threshold")


def open_body(spec: BodySpec, ctx: BodyContext) -> Opened:
    from bridge.serial.gogo import BAUD, GoGoBoard, GoGoBody
    pose = start_pose(spec, ctx)
    baud = int(spec.get("baud", BAUD))
    tuning = {k: spec.options[k] for k in TUNING if k in spec.options}

    def stop(board: GoGoBoard, body: GoGoBody) -> None:
        board.off()
        board.led(False)

    # the body's constructor pings the board and puts it in a known state:
    # a board that does not answer is refused before the mission
    return open_host_body(
        spec, lambda: GoGoBoard(spec.port, baud),
        lambda b: GoGoBody(b, ctx.node, link=ctx.link, arena=ctx.arena, tick_s=ctx.tick_s,
                           clock=ctx.clock, **pose, **tuning),
        stop, f"GoGo Board on {spec.port} at {baud} baud")
