"""`touchswarm dbc`: write the message schema as a DBC file (cantools)."""

from __future__ import annotations

import argparse
from pathlib import Path

from bridge.commands import numbers as N
from bridge.commands.paths import path_arg
from bridge.errors import UsageError


def register(sub) -> None:
    p = sub.add_parser("dbc",
                       description="Generate a DBC from firmware_logic/messages.py and the "
                                   "behaviour's own messages (its spec.MESSAGES) so standard "
                                   "CAN tools (cantools, SavvyCAN, ...) decode the bus.")
    p.add_argument("-o", "--out", type=path_arg, default=Path("touchswarm.dbc"), metavar="FILE",
                   help="where to write it (default: %(default)s; docs/touchswarm.dbc ships)")
    p.add_argument("--max-node", type=N.count(1, 127, "a node id"), default=127, metavar="N",
                   help="highest robot node id to include (default: %(default)s)")
    p.add_argument("--behaviour", default="thesis", metavar="NAME|DIR",
                   help="whose messages, states and models: an installed behaviour or a "
                        "behaviour's folder (default: %(default)s)")
    p.add_argument("--keyed", action="store_true",
                   help="describe a keyed bus (--keys, SecOC) instead: every host command and "
                        "robot report in its sealed 8-byte layout (payload or sealed payload "
                        "fields, then `fv`, the freshness value's low bytes, and `mac`, the "
                        "24-bit MAC); host commands for robots 1..N only (no broadcast on a "
                        "keyed bus)")
    p.set_defaults(func=cmd_dbc)


def cmd_dbc(args: argparse.Namespace) -> int:
    from bridge.commands.paths import check_out_file
    from bridge.links import dbc
    from sim_backend import registry
    check_out_file(args.out, "--out", "touchswarm.dbc")
    try:
        b = registry.load(args.behaviour)
    except registry.BehaviourError as err:
        raise UsageError(f"--behaviour: {err}") from None
    n = dbc.write(args.out, args.max_node, behaviour=b, keyed=args.keyed)
    own = ", ".join(m[1] for m in b.messages)
    print(f"{args.out}: {n} {'sealed (keyed bus) ' if args.keyed else ''}messages for nodes "
          f"0..{args.max_node} "
          f"(behaviour {b.name}{'; its own: ' + own if own else ''})")
    return 0
