"""`touchswarm mission --body NODE=URL ...`: chosen robots are real bodies,
the rest simulated, one host coordinator collecting every touch."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from bridge.commands import numbers as N
from bridge.commands.run import add_scenario_args, check_link_limits, scenario_from_args


def register(sub) -> None:
    p = sub.add_parser(
        "mission",
        description="Run one scenario in which the robots named by --body are real: their "
                    "unchanged firmware runs here, one tick at a time, on a Khepera II or a "
                    "GoGo Board robot over its serial port; every other robot is simulated. "
                    "A real robot's place in the sim world is its own odometry; it senses "
                    "only the real world (the object on the bench, light), while the "
                    "simulated robots see it and follow its beacon. One host coordinator "
                    "collects all touches. Exit status 0 when the object was delivered home, "
                    "1 when not (or a body failed for good mid-way), 2 on bad input, a body "
                    "URL or device included (checked before the first tick).",
        epilog="body URLs (the port is a device path or any pyserial URL):\n"
               "  sim://                                   simulated (the default)\n"
               "  khepera:///dev/ttyUSB0?baud=38400        Khepera II (baud: its mode jumper)\n"
               "  gogo:///dev/ttyUSB1                      GoGo Board robot, 9600 baud\n"
               "  mpy:///dev/ttyACM0                       MicroPython robot (touchswarm deploy "
               "--start);\n"
               "                                           its body is simulated\n"
               "options: x=, y= (patch where the robot is put down; default: the\n"
               "scenario's start of that node; mpy: where its simulated body starts),\n"
               "heading= (degrees clockwise from north, default 0), patch_mm= (floor size\n"
               "of a patch, default 50); khepera: cruise, dark, light_step,\n"
               "touch_threshold; gogo: mm_s_per_level, wheel_base_mm, power, dark,\n"
               "light_step, touch_threshold. docs/serial.md has the details.\n"
               "\nexamples:\n"
               "  touchswarm mission --body 1='khepera:///dev/ttyUSB0?baud=38400&x=0&y=0"
               "&heading=90' \\\n"
               "      --robots 6 --set objectX=2 --set objectY=0 --max-ticks 3000\n"
               "  touchswarm mission --body 3=khepera:///dev/ttyUSB0 --body 5=gogo:///dev/ttyUSB1"
               " --json",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--body", action="append", default=[], required=True, metavar="NODE=URL",
                   help="robot NODE (1..robots) is the body at URL (repeatable, one per node)")
    add_scenario_args(p)
    p.add_argument("--tick-ms", type=N.positive("milliseconds"), default=50.0, metavar="MS",
                   help="tick period on the wall clock; a real body's steering assumes it "
                        "(default: %(default)s)")
    p.add_argument("--max-ticks", type=N.count(1, what="ticks"), metavar="N",
                   help="stop after N ticks (default: the scenario's maxTicks)")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.set_defaults(func=cmd_mission)


def parse_bodies(items: list[str]) -> dict:
    from bridge.bodies import BodyURLError, parse_assignment
    bodies: dict[int, Any] = {}
    for item in items:
        node, spec = parse_assignment(item)
        if node in bodies:
            raise BodyURLError(f"--body {node}= given twice ({bodies[node].url!r} and "
                               f"{spec.url!r}); one body per node")
        bodies[node] = spec
    return bodies


def cmd_mission(args: argparse.Namespace) -> int:
    from bridge.commands.run import format_summary
    from bridge.mission import MixedMission

    bodies = parse_bodies(args.body)
    sc = scenario_from_args(args)
    # real robots' messages carry node ids and patch coordinates as on a real link
    check_link_limits(sc, "serial")
    with MixedMission(sc, args.seed, bodies, tick_s=args.tick_ms / 1000.0) as m:
        for node, (x, y, h) in m.start_poses().items():
            print(f"robot {node}: {m.opened[node].describe()}, put down at patch ({x}, {y}) "
                  f"facing {h:g} degrees", file=sys.stderr, flush=True)
        result = m.run(max_ticks=args.max_ticks)
        summary = m.summary(result)
    if args.json:
        print(json.dumps(summary, sort_keys=True))
    else:
        print(format_summary(summary, sc.behaviour, result.coordinator))
        for node, text in summary["bodies"].items():
            if node in summary["real_touches"]:
                # a body the host steps counts its failed ticks; a tethered
                # board (mpy://) ticks on its own and has none to count
                failed = summary["real_failed_ticks"].get(node)
                print(f"  robot {node:<11} {text}: {summary['real_touches'][node]} touch(es)"
                      + ("" if failed is None else f", {failed} failed tick(s)"))
    return 0 if summary["delivered"] else 1
