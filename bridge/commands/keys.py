"""`touchswarm keys new`: per-robot keys for authenticated host commands on
CAN, and the --keys option that `host` and `robots` share."""

from __future__ import annotations

import argparse
from pathlib import Path

from bridge.commands import numbers as N
from bridge.commands.paths import check_out_file, path_arg
from bridge.errors import UsageError


def register(sub) -> None:
    p = sub.add_parser("keys",
                       description="Without keys, any node on a CAN bus can send the robots "
                                   "HALT, ACK or TRANSPORT and they obey (CAN frames carry no "
                                   "sender). With `host --keys FILE` and `robots --keys FILE`, "
                                   "every host command carries a freshness counter and a "
                                   "24-bit AES-CMAC, and robots drop any that does not verify; "
                                   "a robot's HELLO carries its MAC too, so a key mismatch "
                                   "stops the host at once (docs/protocol.md, 'Authenticated "
                                   "host commands'; docs/security.md).")
    verbs = p.add_subparsers(dest="verb", metavar="SUBCOMMAND", required=True)
    new = verbs.add_parser("new", help="write a new key file (one AES-128 key per robot)")
    new.add_argument("--nodes", type=N.count(1, None, "a robot count"), default=20, metavar="N",
                     help="keys for robots 1..N (default: %(default)s)")
    new.add_argument("--out", type=path_arg, required=True, metavar="FILE",
                     help="the key file to write (owner-only permissions; never overwritten)")
    new.set_defaults(func=cmd_new)


def cmd_new(args: argparse.Namespace) -> int:
    from firmware_logic import messages as msg
    from bridge.links.secoc import new_key_file

    if args.nodes > msg.MAX_NODE:
        raise UsageError(f"--nodes {args.nodes}: a CAN bus has node ids 1..{msg.MAX_NODE}")
    if args.out.exists():
        raise UsageError(f"--out {args.out}: exists already; keys on robots would no longer "
                         "match; choose another file")
    check_out_file(args.out, "--out", "keys.toml")
    new_key_file(args.out, list(range(1, args.nodes + 1)))
    print(f"{args.nodes} keys written to {args.out} (readable by you only); give the same file "
          f"to `touchswarm host --keys` and `touchswarm robots --keys`")
    return 0


def add_keys_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--keys", type=path_arg, metavar="FILE",
                   help="authenticate host commands and HELLOs with this key file (`touchswarm "
                        "keys new`; owner-only); host and robots need the same file; "
                        "freshness counters are kept beside it in FILE.fv.json (host) and "
                        "FILE.robots.fv.json (robots)")


def keys_from_args(args: argparse.Namespace, agents: int) -> dict[int, bytes] | None:
    """The key file's keys, checked to cover every robot; None without --keys."""
    if args.keys is None:
        return None
    from bridge.links.secoc import SecocError, load_keys
    try:
        keys = load_keys(args.keys)
    except SecocError as err:
        raise UsageError(f"--keys: {err}") from None
    missing = [n for n in range(1, agents + 1) if n not in keys]
    if missing:
        raise UsageError(f"--keys {args.keys}: no key for node {missing[0]} (the scenario has "
                         f"{agents} robots, the file {len(keys)} keys)")
    return keys


def freshness_file(keys_path: Path, side: str = "host") -> Path:
    """Where the host (KEYS.fv.json) or the simulated robots
    (KEYS.robots.fv.json) keep their freshness counters: beside the key file."""
    return Path(f"{keys_path}.fv.json" if side == "host" else f"{keys_path}.{side}.fv.json")
