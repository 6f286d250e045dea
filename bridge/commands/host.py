"""`touchswarm host --bus URL`: the host controller as its own process."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from pathlib import Path

from bridge.commands.run import add_scenario_args, scenario_from_args


def register(sub) -> None:
    p = sub.add_parser("host", help="run the host coordinator against a CAN bus and/or serial ports",
                       description="Collect touch reports from robots on a bus, journal each "
                                   "before acknowledging it, and command the transport home. "
                                   "Runs until the object is home or it is stopped.")
    p.add_argument("--bus", metavar="URL",
                   help="virtual://CHANNEL, socketcan://can0, slcan:///dev/ttyACM0?bitrate=500000"
                        " or can://INTERFACE/CHANNEL?bitrate=...")
    p.add_argument("--serial", action="append", default=[], metavar="PORT",
                   help="robots on a framed serial port: device path, "
                        "serial:///dev/ttyUSB0?baud=115200 or any pyserial URL (repeatable; "
                        "may be combined with --bus)")
    p.add_argument("--serial-baud", type=int, default=115200, metavar="BAUD",
                   help="baud rate of --serial ports without ?baud= (default: %(default)s)")
    add_scenario_args(p)
    p.add_argument("--journal", type=Path, metavar="PATH",
                   help="SQLite (WAL) journal written before every ACK "
                        "(default: the --resume journal, else none)")
    p.add_argument("--resume", type=Path, metavar="JOURNAL",
                   help="recover nodes and touches from a journal after a crash")
    p.add_argument("--tick-ms", type=float, default=10.0, metavar="MS",
                   help="host tick period (default: %(default)s)")
    p.add_argument("--max-ticks", type=int, metavar="N", help="give up after N host ticks")
    p.add_argument("--json", action="store_true",
                   help="progress on stderr, one JSON summary on stdout")
    p.set_defaults(func=cmd_host)


def cmd_host(args: argparse.Namespace) -> int:
    from bridge.errors import UsageError
    from bridge.host.journal import Journal, JournalError
    from bridge.host.process import HostProcess
    from bridge.host.transport import CanTransport
    from bridge.links import LinkError, open_bus
    from bridge.transport import FanIn

    sc = scenario_from_args(args)
    if not args.bus and not args.serial:
        raise UsageError("host: give --bus URL and/or --serial PORT (where the robots are)")
    if args.tick_ms <= 0:
        raise UsageError(f"--tick-ms {args.tick_ms}: expected a positive period")
    if args.resume is not None and not args.resume.exists():
        raise UsageError(f"--resume {args.resume}: no such journal")
    out = sys.stderr if args.json else sys.stdout

    def event(text: str) -> None:
        print(text, file=out, flush=True)

    stopping = []
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda *a: stopping.append(1))
    journal_path = args.journal or args.resume
    parts: list = []
    try:
        if args.bus:
            parts.append(CanTransport(open_bus(args.bus)))
        if args.serial:
            from bridge.serial.transport import MultiSerialTransport
            parts.append(MultiSerialTransport.open(args.serial, args.serial_baud))
    except BaseException:
        for part in parts:
            part.close()
        raise
    where = " + ".join(([args.bus] if args.bus else []) + args.serial)
    with (parts[0] if len(parts) == 1 else FanIn(parts)) as transport:
        try:
            journal = Journal(journal_path) if journal_path else None
        except JournalError as err:
            raise UsageError(str(err)) from err
        try:
            host = HostProcess(transport, sc.weight_centi, sc.homeX, sc.homeY, journal=journal,
                               tick_seconds=args.tick_ms / 1000.0, on_event=event)
            if args.resume is not None:
                assert journal is not None      # journal_path defaults to the resumed one
                if args.resume.resolve() != Path(journal_path).resolve():
                    with Journal(args.resume) as old:     # carry it over, then go on there
                        for n, (m, pw) in old.nodes().items():
                            journal.add_node(n, m, pw)
                        for t in old.touches():
                            journal.add_touch(t)
                host.resume(journal)
            event(f"host on {where}: object weight {sc.weight_centi}, home "
                  f"({sc.homeX},{sc.homeY}), journal {journal_path or 'none'}")
            try:
                summary = host.run(stop=lambda: bool(stopping), max_ticks=args.max_ticks)
            except LinkError as err:
                if not host.coord.delivered_tick >= 0:
                    raise
                event(f"bus closed after delivery ({err})")
                summary = host.summary()
        finally:
            if journal is not None:
                journal.close()
    if args.json:
        print(json.dumps(summary, sort_keys=True), flush=True)
    else:
        print(f"{'DELIVERED' if summary['delivered'] else 'NOT delivered'}: "
              f"{len(summary['touches'])} touches, power {summary['power']:g}, "
              f"leader {summary['leader']}, home at tick {summary['home_tick']}, "
              f"{summary['duplicates']} duplicates ignored, bad frames {summary['bad_frames']}")
    return 0 if summary["delivered"] else 1
