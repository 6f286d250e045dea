"""`touchswarm dbc`: write the message schema as a DBC file (cantools)."""

from __future__ import annotations

import argparse
from pathlib import Path

from bridge.errors import UsageError


def register(sub) -> None:
    p = sub.add_parser("dbc", help="write the CAN message schema as a DBC file",
                       description="Generate a DBC from firmware_logic/messages.py so standard "
                                   "CAN tools (cantools, SavvyCAN, ...) decode the bus.")
    p.add_argument("-o", "--out", type=Path, default=Path("touchswarm.dbc"), metavar="FILE",
                   help="where to write it (default: %(default)s; docs/touchswarm.dbc ships)")
    p.add_argument("--max-node", type=int, default=127, metavar="N",
                   help="highest robot node id to include (default: %(default)s)")
    p.set_defaults(func=cmd_dbc)


def cmd_dbc(args: argparse.Namespace) -> int:
    from bridge.links import dbc
    if not 1 <= args.max_node <= 127:
        raise UsageError(f"--max-node {args.max_node}: expected 1..127")
    n = dbc.write(args.out, args.max_node)
    print(f"{args.out}: {n} messages for nodes 0..{args.max_node}")
    return 0
