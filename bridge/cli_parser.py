"""The command line's parser (bridge/cli.py holds the command table,
main and the exit status): the top-level options, and one sub-parser per
command of COMMANDS, built when the command line names it.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
TYPE_CHECKING = False           # typing's, for mypy: `touchswarm --help` imports no typing
if TYPE_CHECKING:
    from typing import NoReturn

from bridge.cli import COMMANDS, EXIT_USAGE


class OneLineParser(argparse.ArgumentParser):
    """argparse prints the whole usage block before an error; a user who
    mistyped one option needs the one line naming it, and where to look."""

    def error(self, message: str) -> NoReturn:
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message} (see `{self.prog} --help`)\n")

    # argparse sizes every formatter (add_argument's metavar check too) by
    # shutil.get_terminal_size, and shutil imports bz2, lzma and zlib: ~7 M
    # instructions of start-up, for `run` as for --help. terminal_columns
    # is that function's width without that import.
    def _get_formatter(self) -> argparse.HelpFormatter:
        # every HelpFormatter takes width (typeshed types the class by prog alone)
        return self.formatter_class(prog=self.prog,  # type: ignore[call-arg]
                                    width=terminal_columns() - 2)


def terminal_columns() -> int:
    """shutil.get_terminal_size().columns: $COLUMNS when a positive number,
    else the terminal's width on standard output, else 80."""
    try:
        columns = int(os.environ["COLUMNS"])
    except (KeyError, ValueError):
        columns = 0
    out = sys.__stdout__
    if columns <= 0 and out is not None:
        try:
            columns = os.get_terminal_size(out.fileno()).columns
        except (ValueError, OSError):
            columns = 0
    return columns if columns > 0 else 80


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
        from sim_backend.version import version
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
