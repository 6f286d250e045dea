"""The touchswarm command line. Commands are one flat table; each module
registers its own sub-parser and keeps heavy imports inside its handler.

Exit status (docs/cli.md): 0 success; 1 the command ran and its outcome is a
failure (object not delivered, replay divergence, a device failed mid-way);
2 bad input, refused before any work (arguments, files, output paths,
addresses); 130 interrupted. Every error is one line on stderr, never a
traceback.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from typing import NoReturn

from bridge.errors import BridgeError, UsageError

# one module per command; each has register(subparsers) and keeps its heavy
# imports (python-can, pyserial, numpy) inside its handler
COMMANDS = [
    "bridge.commands.run",
    "bridge.commands.mission",
    "bridge.commands.scenarios",
    "bridge.commands.behaviours",
    "bridge.firmware.cli",
    "bridge.commands.dbc",
    "bridge.commands.host",
    "bridge.commands.robots",
    "bridge.commands.replay",
    "bridge.commands.deploy",
    "bridge.commands.sweep",
    "bridge.commands.keys",
    "bridge.commands.view",
]

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


class OneLineParser(argparse.ArgumentParser):
    """argparse prints the whole usage block before an error; a user who
    mistyped one option needs the one line naming it, and where to look."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")


def _version() -> str:
    from sim_backend.api import version
    return version()


def build_parser() -> argparse.ArgumentParser:
    p = OneLineParser(
        prog="touchswarm",
        description="Touch-only swarm robots that perceive an object's shape incrementally "
                    "and carry it home: one firmware FSM for simulation, CAN, serial and "
                    "real robots.",
        epilog="examples:\n"
               "  touchswarm run --scenario ant --seed 7\n"
               "  touchswarm sweep --grid sigRadius=3,5,8 --seeds 50\n"
               "  touchswarm run --link can --record run.blf && touchswarm replay run.blf\n"
               "\n`touchswarm COMMAND --help` explains each command. Exit status: 0 success, "
               "1 the outcome\nis a failure (not delivered, divergence, device failure), "
               "2 bad input (nothing was\ndone), 130 interrupted; docs/cli.md.",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("-v", "--verbose", action="count", default=0, help="log more (-vv: debug)")
    p.add_argument("--version", action="version", version=f"%(prog)s {_version()}",
                   help="print the installed version and exit")
    # sub-parsers are built by type(p), so every command's errors are one line too
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
        return EXIT_USAGE
    from firmware_logic.registry import BehaviourError
    from sim_backend.errors import SimError
    try:
        return args.func(args)
    except (UsageError, SimError, BehaviourError) as err:
        # BehaviourError: a behaviour that loads but does not hold together
        # (e.g. robot_args that do not fit its constructor), found when used
        print(f"touchswarm: error: {err}", file=sys.stderr)
        return EXIT_USAGE
    except BridgeError as err:
        print(f"touchswarm: {err}", file=sys.stderr)
        return EXIT_FAILED
    except OSError as err:
        # inputs and outputs are checked before the work starts, so this is
        # the machine failing mid-way (disk full, device gone): one line too
        where = f"{err.filename}: " if err.filename else ""
        print(f"touchswarm: {where}{err.strerror or err}", file=sys.stderr)
        return EXIT_FAILED
    except KeyboardInterrupt:
        return EXIT_INTERRUPTED


if __name__ == "__main__":
    sys.exit(main())
