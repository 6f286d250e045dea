"""The touchswarm command line. Commands are one flat table; each module
registers its own sub-parser and keeps heavy imports inside its handler."""

from __future__ import annotations

import argparse
import importlib
import logging
import sys

from bridge.errors import BridgeError, UsageError

# one module per command; each has register(subparsers) and keeps its heavy
# imports (python-can, pyserial, numpy) inside its handler
COMMANDS = [
    "bridge.commands.run",
    "bridge.commands.scenarios",
    "bridge.commands.behaviours",
    "bridge.firmware.cli",
    "bridge.commands.dbc",
    "bridge.commands.host",
    "bridge.commands.robots",
    "bridge.commands.replay",
    "bridge.commands.deploy",
    "bridge.commands.sweep",
]


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="touchswarm",
        description="Touch-only swarm robots that perceive an object's shape incrementally "
                    "and carry it home: one firmware FSM for simulation, CAN, serial and "
                    "real robots.")
    p.add_argument("-v", "--verbose", action="count", default=0, help="log more (-vv: debug)")
    sub = p.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(name).register(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.WARNING - 10 * min(args.verbose, 2),
                        format="%(levelname)s %(name)s: %(message)s")
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    from sim_backend.errors import SimError
    try:
        return args.func(args)
    except (UsageError, SimError) as err:
        print(f"touchswarm: error: {err}", file=sys.stderr)
        return 2
    except BridgeError as err:
        print(f"touchswarm: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        return 130


if __name__ == "__main__":
    sys.exit(main())
