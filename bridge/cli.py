"""The touchswarm command line. Commands are one flat table (COMMANDS: name,
module, one-line help); a command's module is imported, and registers its
sub-parser, only when the command line names it (or every one for
docs/cli.md), and keeps heavy imports inside its handler.

Exit status (docs/cli.md): 0 success; 1 the command ran and its outcome is a
failure (object not delivered, replay divergence, a device failed mid-way);
2 bad input, refused before any work (arguments, files, output paths,
addresses); 130 interrupted. Every error is one line on stderr, never a
traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from typing import NoReturn

from bridge.errors import BridgeError, UsageError

# Every command: its name, the module whose register(subparsers) builds its
# parser, and its one-line help (listed by `touchswarm --help`; written only
# here: a module's add_parser takes it from this table). Only the chosen
# command's module is imported, so `touchswarm --version`, `--help` and
# `run` do not pay for the others; each module also keeps its heavy imports
# (python-can, pyserial, numpy, matplotlib) inside its handlers.
COMMANDS: dict[str, tuple[str, str]] = {
    "run": ("bridge.commands.run", "run the whole mission in the simulated world"),
    "mission": ("bridge.commands.mission",
                "run a mission with some robots on real bodies (Khepera II, GoGo)"),
    "scenarios": ("bridge.commands.scenarios", "list built-in scenarios and the scenario keys"),
    "behaviours": ("bridge.commands.behaviours", "list the installed behaviours"),
    "behaviour": ("bridge.commands.behaviours", "make a new behaviour from a scaffold"),
    "firmware": ("bridge.firmware.cli",
                 "check the robot firmware (subset rules, MicroPython conformance)"),
    "dbc": ("bridge.commands.dbc", "write the CAN message schema as a DBC file"),
    "host": ("bridge.commands.host",
             "run the host coordinator against a CAN bus and/or serial ports"),
    "robots": ("bridge.commands.robots", "run the simulated swarm as nodes on a CAN bus"),
    "replay": ("bridge.commands.replay", "replay a recorded run against the firmware and host"),
    "deploy": ("bridge.commands.deploy",
               "check, compile and copy the robot firmware to a MicroPython board"),
    "sweep": ("bridge.commands.sweep",
              "run a grid of parameters x seeds; tidy CSV and the thesis's plots"),
    "keys": ("bridge.commands.keys", "make keys for authenticated host commands on CAN"),
    "view": ("bridge.commands.view",
             "watch a mission live in the browser (a simulated run or a host journal)"),
}

EXIT_OK, EXIT_FAILED, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130


class OneLineParser(argparse.ArgumentParser):
    """argparse prints the whole usage block before an error; a user who
    mistyped one option needs the one line naming it, and where to look."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")

    # add_argument checks each metavar with a throw-away formatter, whose
    # default width is the terminal's: shutil (and with it bz2, lzma, zlib),
    # about 7 M instructions of a run's start-up for text nobody reads. The
    # check formats no line, so its formatter gets a fixed width; help and
    # usage keep the terminal's.
    _checking = False

    def add_argument(self, *args, **kwargs) -> argparse.Action:
        self._checking = True
        try:
            return super().add_argument(*args, **kwargs)
        finally:
            self._checking = False

    def _get_formatter(self) -> argparse.HelpFormatter:
        if self._checking:
            # every HelpFormatter takes width (typeshed types the class by prog alone)
            return self.formatter_class(prog=self.prog, width=80)  # type: ignore[call-arg]
        return super()._get_formatter()


class LazyCommands(argparse._SubParsersAction):
    """The sub-parsers of COMMANDS, each built only when needed: `touchswarm
    --help` lists them from the table alone; the chosen command's module is
    imported and its parser built when the command line names it; load()
    builds them all (docs/cli.md)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        for name, (_module, help) in COMMANDS.items():
            # a placeholder keeps the table's order and makes the name a valid
            # choice; the module's add_parser puts the parser in its place
            self._name_parser_map[name] = None
            self._choices_actions.append(self._ChoicesPseudoAction(name, (), help))

    def add_parser(self, name: str, **kwargs):
        if name not in COMMANDS:
            raise ValueError(f"command {name!r} is not in bridge/cli.py COMMANDS")
        if "help" in kwargs:
            raise ValueError(f"command {name!r}: its one-line help is in bridge/cli.py COMMANDS")
        if self._name_parser_map.get(name) is not None:
            raise argparse.ArgumentError(self, f"conflicting subparser: {name}")
        kwargs.setdefault("prog", f"{self._prog_prefix} {name}")
        parser = self._parser_class(**kwargs)
        self._name_parser_map[name] = parser
        return parser

    def load(self, name: str | None = None) -> None:
        """Build the parser of command `name`, or of every command."""
        for other, (module, _help) in COMMANDS.items():
            if (name is None or other == name) and self._name_parser_map[other] is None:
                importlib.import_module(module).register(self)
                if self._name_parser_map[other] is None:
                    raise ValueError(f"{module}.register did not build command {other!r}")

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        if values and values[0] in COMMANDS:
            self.load(values[0])
        super().__call__(parser, namespace, values, option_string)


class LazyVersion(argparse._VersionAction):
    """--version reads the installed version only when it is asked for."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        from sim_backend.api import version
        self.version = f"%(prog)s {version()}"
        super().__call__(parser, namespace, values, option_string)


def build_parser(full: bool = False) -> argparse.ArgumentParser:
    """The command line's parser. Each command's sub-parser is built when the
    arguments name it; `full` builds every one now (to list them all, e.g.
    docs/cli.md)."""
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
    p.add_argument("--version", action=LazyVersion,
                   help="print the installed version and exit")
    # sub-parsers are built by type(p), so every command's errors are one line too
    # prog given: argparse would format the usage line (a terminal-wide formatter) to find it
    sub = p.add_subparsers(dest="command", metavar="COMMAND", action=LazyCommands,
                           prog=p.prog)
    if full:
        sub.load()
    return p


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    rc: int | str | None = EXIT_FAILED
    try:
        rc = _main(argv)
        return rc
    except SystemExit as done:          # --help, --version, argparse's errors
        rc = done.code
        raise
    finally:
        _log_argv(argv, rc)


def _log_argv(argv: list[str], rc: int | str | None) -> None:
    """The suite's record of the command lines it ran (TOUCHSWARM_ARGV_LOG,
    set by conftest.py): every command in README and the guide must appear
    there with exit status 0 (tests/doc_commands.py). One JSON line each,
    appended whole, so processes running side by side do not mix lines."""
    path = os.environ.get("TOUCHSWARM_ARGV_LOG")
    if not path:
        return
    import json
    line = json.dumps({"argv": argv, "rc": rc if isinstance(rc, int) else (0 if rc is None else 1)})
    fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o600)
    try:
        os.write(fd, (line + "\n").encode())
    finally:
        os.close(fd)


def configure_logging(verbose: int) -> None:
    """Records of WARNING and above (-v: INFO, -vv: DEBUG) on stderr, one
    line each naming the logger."""
    import logging
    logging.basicConfig(level=logging.WARNING - 10 * min(verbose, 2),
                        format="%(levelname)s %(name)s: %(message)s")


def _main(argv: list[str]) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    # a command may set quiet_logging: it configures logging itself on the
    # paths whose modules log, so its plain path imports no logging
    if args.verbose or not getattr(args, "quiet_logging", False):
        configure_logging(args.verbose)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_USAGE
    from sim_backend.errors import SimError
    from sim_backend import registry
    registry.untrust_all()     # only this command line's folders are trusted
    try:
        return args.func(args)
    except (UsageError, SimError) as err:
        # SimError includes BehaviourError: a behaviour that loads but does not
        # hold together (e.g. robot_args that do not fit its constructor)
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
