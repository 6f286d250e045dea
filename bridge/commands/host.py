"""`touchswarm host --bus URL`: the host controller as its own process."""

from __future__ import annotations

import argparse
import json
import signal
import sys
import threading
from pathlib import Path
from typing import Any

from bridge.commands import numbers as N
from bridge.commands.keys import add_keys_arg, freshness_file, keys_from_args
from bridge.commands.paths import check_out_file, path_arg
from bridge.commands.run import add_scenario_args, scenario_from_args

# Silence limits (seconds). A robot sends at least one frame every 64 of its
# ticks (HEARTBEAT; TOUCH retransmissions back off to 64 ticks too): 0.64 s at
# the 10 ms tick, 6.4 s at 100 ms. The node limit leaves room for slow robot
# ticks; the bus limit also covers robots being switched on after the host.
NODE_TIMEOUT = 20.0
BUS_TIMEOUT = 60.0


def register(sub) -> None:
    p = sub.add_parser("host",
                       description="Collect touch reports from robots on a bus, journal each "
                                   "before acknowledging it, and command the transport home. "
                                   "Runs until the object is home, it is stopped, or the "
                                   "robots fall silent (--node-timeout, --bus-timeout). Exit "
                                   "status: 0 delivered (the host's own model has the object home), "
                                   "1 any other outcome (halted; stalled, the object stuck or the "
                                   "robots silent; stopped: the summary's outcome and reason say "
                                   "which) or a link or journal failure, 2 a usage error.")
    p.add_argument("--bus", metavar="URL",
                   help="socketcan://can0, slcan:///dev/ttyACM0?bitrate=500000 (or the "
                        "robots' slcan-pty face: slcan:///tmp/adapter?settle_ms=0) or "
                        "can://INTERFACE/CHANNEL?bitrate=...; not virtual://, which does "
                        "not cross processes")
    p.add_argument("--serial", action="append", default=[], metavar="PORT",
                   help="robots on a framed serial port: device path, "
                        "serial:///dev/ttyUSB0?baud=115200 or any pyserial URL (repeatable; "
                        "may be combined with --bus)")
    p.add_argument("--serial-baud", type=N.count(1, what="a baud rate"), default=115200, metavar="BAUD",
                   help="baud rate of --serial ports without ?baud= (default: %(default)s)")
    add_scenario_args(p)
    p.add_argument("--journal", type=path_arg, metavar="PATH",
                   help="SQLite (WAL) journal written before every ACK "
                        "(default: the --resume journal, else none)")
    p.add_argument("--resume", type=path_arg, metavar="JOURNAL",
                   help="replay a journal's reports and decisions after a crash "
                        "(layout version 2; an older journal is refused)")
    p.add_argument("--tick-ms", type=N.positive("milliseconds"), default=10.0, metavar="MS",
                   help="host tick period (default: %(default)s)")
    p.add_argument("--max-ticks", type=N.count(1, what="ticks"), metavar="N", help="give up after N host ticks")
    p.add_argument("--node-timeout", type=N.at_least(0, "seconds", " (0: never give up)"), default=NODE_TIMEOUT, metavar="S",
                   help="give up (outcome stalled, exit 1) when a carrier, a robot whose touch was accepted, "
                        "is silent this long; robots send a HEARTBEAT at least every 64 of "
                        "their ticks (0: never; default: %(default)s)")
    p.add_argument("--bus-timeout", type=N.at_least(0, "seconds", " (0: never give up)"), default=BUS_TIMEOUT, metavar="S",
                   help="give up (outcome stalled, exit 1) when no robot at all is heard this long, start-up "
                        "included (0: never; default: %(default)s)")
    add_keys_arg(p)
    p.add_argument("--json", action="store_true",
                   help="progress on stderr, one JSON summary on stdout")
    p.set_defaults(func=cmd_host)


def cmd_host(args: argparse.Namespace) -> int:
    from bridge.host.process import host_behaviour
    from bridge.links import LinkError

    sc = scenario_from_args(args)
    # a behaviour the host process cannot run is refused before any port opens
    host_behaviour(sc.behaviour, sc)
    _check_ports(args)
    sealer = _sealer(args, sc)
    if args.resume is not None:
        check_resumable(args.resume)
    out = sys.stderr if args.json else sys.stdout

    def event(text: str) -> None:
        print(text, file=out, flush=True)

    stopping: list[int] = []
    if threading.current_thread() is threading.main_thread():
        signal.signal(signal.SIGTERM, lambda *a: stopping.append(1))
    # the journal first: a wrong path is found before any port is touched
    journal = _open_journal(args, sc)
    try:
        host = _make_host(args, sc, journal, event)
        if sealer is not None:
            # a sealed TOUCH's power is its node's HELLO's (from the journal too),
            # and a resumed host looks for its predecessor's counters once per node
            sealer.nodes = host.coord.nodes
            sealer.resumed = args.resume is not None
        transport = _open_transport(args, sealer)
    except BaseException:
        if journal is not None:
            journal.close()
        raise
    where = " + ".join(([args.bus] if args.bus else []) + args.serial)
    with transport:
        try:
            host.transport = transport
            event(f"host on {where}: {_load_words(host.behaviour, sc)}home "
                  f"({sc.homeX},{sc.homeY}), journal {args.journal or args.resume or 'none'}")
            try:
                summary = host.run(stop=lambda: bool(stopping), max_ticks=args.max_ticks,
                                   node_timeout=args.node_timeout or None,
                                   bus_timeout=args.bus_timeout or None)
            except LinkError as err:
                if not host.coord.done():
                    raise
                event(f"bus closed after the mission ended ({err})")
                summary = host.finish()
        finally:
            if journal is not None:
                journal.close()
    return _result(args, host, summary)


def _check_ports(args: argparse.Namespace) -> None:
    """--bus and --serial name ports that can be opened (nothing is opened)."""
    from bridge import devices
    from bridge.errors import UsageError
    from bridge.links import check_device, parse_url, refuse_in_process
    if not args.bus and not args.serial:
        raise UsageError("host: give --bus URL and/or --serial PORT (where the robots are)")
    if args.bus:
        parse_url(args.bus)
        refuse_in_process(args.bus, "host")
        check_device(args.bus, "host")
    for port in args.serial:
        why = devices.missing(port)
        if why:
            raise UsageError(f"--serial {port}: {why}")


def _sealer(args: argparse.Namespace, sc: Any) -> Any:
    """The sealer of authenticated host commands (--keys), else None."""
    from bridge.errors import UsageError
    keys = keys_from_args(args, sc.agents)
    if keys is None:
        return None
    from bridge.links.secoc import FreshnessStore, SecocError, Sealer
    fv_path = freshness_file(args.keys)
    check_out_file(fv_path, "--keys (freshness file)", fv_path.name)
    try:
        return Sealer(keys, FreshnessStore(fv_path))
    except SecocError as err:
        raise UsageError(f"--keys: {err}") from None


def _open_journal(args: argparse.Namespace, sc: Any) -> Any:
    """The mission's journal (--journal, else the --resume one; None without
    either), bound to the behaviour; a resumed journal given another
    --journal is carried over to it first."""
    from bridge.errors import UsageError
    from bridge.host.journal import Journal, JournalError
    journal_path = args.journal or args.resume
    journal = None
    try:
        if journal_path:
            journal = Journal(journal_path)
            if args.resume is None or args.resume.resolve() != Path(journal_path).resolve():
                # a mission goes on in its own journal, or into a new one;
                # never into a journal that holds another mission
                refuse_appending(journal, args.resume)
            if args.resume is not None and args.resume.resolve() != Path(journal_path).resolve():
                with Journal(args.resume) as old:     # carry it over, then go on there
                    journal.copy_from(old)
            journal.bind(sc.behaviour)     # a journal of another behaviour is refused here
    except JournalError as err:
        if journal is not None:
            journal.close()
        raise UsageError(str(err)) from err
    return journal


def _make_host(args: argparse.Namespace, sc: Any, journal: Any, event: Any) -> Any:
    """The host and its resumed state before any port opens: a journal it
    cannot resume is one line, and no robot has been told anything."""
    from bridge.errors import UsageError
    from bridge.host.journal import JournalError
    from bridge.host.process import HostProcess, NotOpen
    try:
        # the host knows the arena, not the object: the robots may be real
        host = HostProcess(NotOpen(), sc.weight_centi, sc.homeX, sc.homeY, journal=journal,
                           tick_seconds=args.tick_ms / 1000.0, on_event=event,
                           world_size=sc.worldSize, behaviour=sc.behaviour,
                           scenario=sc)
        if args.resume is not None:
            assert journal is not None      # journal_path defaults to the resumed one
            host.resume(journal)
    except JournalError as err:
        raise UsageError(f"--resume {args.resume}: {err}") from None
    return host


def _open_transport(args: argparse.Namespace, sealer: Any) -> Any:
    """One transport over every --bus and --serial port (closed again if
    one of them fails to open)."""
    from bridge.host.transport import CanTransport
    from bridge.links import open_bus
    from bridge.transport import FanIn
    parts: list = []
    try:
        if args.bus:
            parts.append(CanTransport(open_bus(args.bus), sealer=sealer))
        if args.serial:
            from bridge.serial.transport import MultiSerialTransport
            parts.append(MultiSerialTransport.open(args.serial, args.serial_baud))
    except BaseException:
        for part in parts:
            part.close()
        raise
    return parts[0] if len(parts) == 1 else FanIn(parts)


def _result(args: argparse.Namespace, host: Any, summary: dict) -> int:
    """Print the summary (one JSON object with --json, else one line); the
    exit code: 0 delivered, 1 not, EXIT_SILENT when the robots went silent."""
    if args.json:
        print(json.dumps(summary, sort_keys=True), flush=True)
    else:
        print(host_line(host.behaviour, summary))
    if summary["gave_up"]:
        limit = {"bus": "--bus-timeout", "node": "--node-timeout"}[summary["gave_up_on"]]
        print(f"touchswarm: host gave up at tick {summary['ticks']}: {summary['gave_up']} "
              f"({limit})", file=sys.stderr, flush=True)
    return exit_status(summary["outcome"])


def exit_status(outcome: str) -> int:
    """The exit status of a host run: its outcome alone decides (docs/cli.md
    "Exit status"): 0 delivered, 1 every other outcome (halted, stalled,
    whether the object stuck or the robots fell silent, stopped); the
    summary's outcome and reason say which."""
    return 0 if outcome == "delivered" else 1


def check_resumable(path: Path) -> None:
    """--resume names a journal: not missing, not empty, a host journal of
    this layout (one line each, before any port opens)."""
    from bridge.errors import UsageError
    from bridge.host.journal import Journal, JournalError
    if not path.exists():
        raise UsageError(f"--resume {path}: no such journal")
    if not path.is_file():
        raise UsageError(f"--resume {path}: not a regular file")
    if path.stat().st_size == 0:
        raise UsageError(f"--resume {path}: an empty file (0 bytes), not a journal; start a "
                         f"new mission with --journal {path} instead")
    try:
        Journal(path, readonly=True).close()
    except JournalError as err:
        raise UsageError(f"--resume {path}: {err}") from None


def refuse_appending(journal, resume: Path | None = None) -> None:
    """A journal that holds a mission is only ever resumed: a second mission
    appended to it (a new one, or another journal's resumed into it) would
    be mixed with the first on a later resume."""
    from bridge.host.journal import JournalError
    held = journal.held()
    if not held:
        return
    end = journal.outcome()
    state = (f"its mission ended {end['outcome']} at tick {end['tick']}" if end
             else "a mission in progress")
    into = f" to resume {resume} into" if resume is not None else ""
    raise JournalError(f"--journal {journal.path} already holds {held} entries ({state}), "
                       f"not a journal{into} for a new mission; go on with that mission "
                       f"with --resume {journal.path}, or give a new --journal")


def _load_words(behaviour, sc) -> str:
    """The object's weight, for a behaviour that declares a load (spec.LOAD,
    the thesis's power against weight); nothing for one that carries nothing."""
    from sim_backend import words
    return f"object weight {sc.weight_centi}, " if words.of(behaviour).load else ""


def host_line(behaviour, summary: dict) -> str:
    """The host's one-line result in the behaviour's words (sim_backend/words.py):
    its RESULT word, the touches, its load and leader when it declares a load
    (the thesis: power), the end tick, duplicates and bad frames."""
    from sim_backend import words
    w = words.of(behaviour)
    key, yes, no = w.result
    load = f", {w.load[0]} {summary[w.load[0]]:g}" if w.load and w.load[0] in summary else ""
    # the leader carries the load (the thesis's transport): no word for one that carries nothing
    leader = f", leader {summary['leader']}" if w.load else ""
    done = summary[key] and summary["outcome"] == "delivered"
    why = "" if done else f" ({summary['outcome']}: {summary['reason']})"
    return (f"{yes if done else no}{why}: {len(summary['touches'])} touches{load}"
            f"{leader}, ended at tick {summary['home_tick']}, "
            f"{summary['duplicates']} duplicates ignored, bad frames {summary['bad_frames']}")
