"""`touchswarm robots --bus URL`: the simulated swarm as nodes on a bus."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
import time

from bridge.commands import numbers as N
from bridge.commands.keys import add_keys_arg, freshness_file, keys_from_args
from bridge.commands.paths import check_out_file
from bridge.commands.run import add_scenario_args, check_link_limits, scenario_from_args


def register(sub) -> None:
    p = sub.add_parser("robots",
                       description="Every simulated robot runs its firmware and talks to the "
                                   "host over one gateway bus. slcan-pty://PATH serves the "
                                   "swarm as an SLCAN adapter on a pseudo-terminal linked at "
                                   "PATH, for a host on slcan://PATH.")
    p.add_argument("--bus", required=True, metavar="URL",
                   help="socketcan://can0, slcan://..., can://..., or "
                        "slcan-pty:///tmp/adapter; not virtual://, which does not cross "
                        "processes")
    add_scenario_args(p)
    p.add_argument("--tick-ms", type=N.positive("milliseconds"), default=10.0, metavar="MS",
                   help="robot tick period (default: %(default)s)")
    p.add_argument("--loss", type=N.share, default=0.0, help="drop this share of frames")
    p.add_argument("--dup", type=N.share, default=0.0, help="duplicate this share of frames")
    p.add_argument("--reorder", type=N.count(1, what="a window of frames"), default=1, metavar="W",
                   help="shuffle frames within windows of W (default: 1, no reordering)")
    p.add_argument("--linger-ms", type=N.at_least(0, "milliseconds"), default=500.0, metavar="MS",
                   help="keep the bus open this long after every robot halted")
    add_keys_arg(p)
    p.add_argument("--json", action="store_true", help="print one JSON summary")
    p.set_defaults(func=cmd_robots)


def cmd_robots(args: argparse.Namespace) -> int:
    from bridge.errors import UsageError
    from bridge.host.swarm import run_swarm, swarm_engine
    from bridge.links import check_device, open_bus, parse_url, refuse_in_process
    from bridge.links.canlink import Faults

    parse_url(args.bus)
    refuse_in_process(args.bus, "robots")
    check_device(args.bus, "robots")
    sc = scenario_from_args(args)
    check_link_limits(sc, "CAN")
    keys = keys_from_args(args, sc.agents)
    fresh = None
    if keys is not None:
        # the robots' counters survive a restart (a real robot: its flash),
        # so nothing the host sealed before is taken again
        from bridge.links.secoc import FreshnessStore, SecocError
        fv_path = freshness_file(args.keys, "robots")
        check_out_file(fv_path, "--keys (the robots' freshness file)", fv_path.name)
        try:
            fresh = FreshnessStore(fv_path)
        except SecocError as err:
            raise UsageError(f"--keys: {err}") from None
    try:
        up = Faults(args.seed, args.loss, args.dup, args.reorder)
        down = Faults(args.seed + 1, args.loss, args.dup, args.reorder)
    except ValueError as err:
        raise UsageError(f"--loss/--dup/--reorder: {err}") from err
    faulty = args.loss or args.dup or args.reorder > 1
    stopping = []
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda *a: stopping.append(1))
    with open_bus(args.bus) as bus:
        engine = swarm_engine(sc, args.seed, bus, up if faulty else None,
                              down if faulty else None, keys=keys, fresh=fresh)
        print(f"{sc.agents} robots on {args.bus}, tick {args.tick_ms} ms"
              f"{', host commands authenticated' if keys else ''}", file=sys.stderr,
              flush=True)
        summary = run_swarm(engine, args.tick_ms / 1000.0, stop=lambda: bool(stopping))
        end = time.monotonic() + args.linger_ms / 1000.0
        while time.monotonic() < end and not stopping:
            engine.link.drain(None)
            time.sleep(0.01)
    if args.json:
        print(json.dumps(summary, sort_keys=True), flush=True)
    else:
        print(f"{summary['robots']} robots, {summary['ticks']} ticks, "
              f"{'all halted' if summary['halted'] else 'not all halted'}; "
              f"reports {summary['reported']}, unacknowledged {summary['unacked']}")
    return 0 if summary["halted"] else 1
