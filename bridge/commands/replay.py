"""`touchswarm replay FILE`: re-run the firmware and the coordinator on a recording."""

from __future__ import annotations

import argparse

from bridge.commands.run import add_trust_arg
import json
import sys

from bridge.commands.paths import path_arg


def register(sub) -> None:
    from bridge.record.formats import FORMATS
    p = sub.add_parser(
        "replay",
        description="Re-run every robot's firmware on its recorded sensor stream and the "
                    "coordinator on the recorded reports; report each decision that differs, "
                    "and any difference from the run summary in the sidecar FILE.json. "
                    "Before replaying, the recording is checked against its sidecar: a "
                    "truncated, corrupt or mismatched recording is refused. Exit status 0 "
                    "when every decision matches, 1 on any divergence, 2 when the recording "
                    "or its sidecar is missing, unreadable, truncated or mismatched.",
        epilog="examples:\n"
               "  touchswarm run --link can --record run.blf && touchswarm replay run.blf\n"
               "  touchswarm replay --json hil_tests/data/golden_ant.blf\n"
               "\nA sidecar without a frame count (written by another tool) is replayed "
               "with a warning:\ntruncation cannot be detected then.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("file", type=path_arg, metavar="FILE",
                   help="a recording made by `touchswarm run --record` (%s), with its "
                        "sidecar FILE.json beside it" % ", ".join(FORMATS))
    p.add_argument("--realtime", action="store_true",
                   help="pace by the recorded timestamps (default: as fast as possible)")
    p.add_argument("--behaviour", type=path_arg, default=None, metavar="DIR",
                   help="the folder of the behaviour the recording ran, when it is not "
                        "where the sidecar says (a path relative to the recording's folder)")
    add_trust_arg(p)
    p.add_argument("--json", action="store_true", help="print the summary as one JSON object")
    p.set_defaults(func=cmd_replay)


def outcome(tick: int | None) -> str:
    """The replayed outcome in the recorded behaviour's words (spec.RESULT:
    the thesis's "delivered at tick N", another's "done at tick N")."""
    from sim_backend import registry, words
    _, yes, no = words.of(registry.active()).result
    return f"{yes.lower()} at tick {tick}" if tick is not None else no.lower()


def cmd_replay(args: argparse.Namespace) -> int:
    from bridge.commands.run import trust_from_args
    from bridge.record.replay import replay
    trust_from_args(args)
    s = replay(args.file, realtime=args.realtime, folder=args.behaviour)
    for w in s["warnings"]:
        print(f"touchswarm: warning: {w}", file=sys.stderr)
    if args.json:
        print(json.dumps(s, sort_keys=True))
    else:
        for d in s["differences"]:
            print(f"DIVERGED {d}")
        if s["divergences"] > len(s["differences"]):
            print(f"... and {s['divergences'] - len(s['differences'])} more")
        print(f"{s['recording']}: {s['robots']} robots, {s['ticks']} ticks, {s['frames']} frames; "
              f"{s['sensor_readings']} sensor readings, {s['actions']} actions, "
              f"{s['robot_messages']} robot messages, {s['host_commands']} host commands "
              f"replayed; {s['touches']} touches, {outcome(s['delivered_tick'])}; "
              f"{s['divergences']} divergences")
    return 1 if s["divergences"] else 0
