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

import os
import sys
TYPE_CHECKING = False           # typing's, for mypy: `touchswarm --version` imports no typing
if TYPE_CHECKING:
    from typing import Any

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

# the parser is built in bridge/cli_parser.py: `touchswarm --version` alone
# prints without importing argparse (gettext with it)
PARSER_NAMES = ("OneLineParser", "LazyCommands", "LazyVersion", "build_parser")


def __getattr__(name: str) -> Any:
    if name in PARSER_NAMES:
        from bridge import cli_parser
        return getattr(cli_parser, name)
    raise AttributeError(f"module 'bridge.cli' has no attribute {name!r}")


# set by a command whose process may end without the interpreter's teardown
# (every file it wrote closed, no object's finaliser left to matter)
_TEARDOWN_SKIPPABLE: list[bool] = []


def skip_teardown() -> None:
    """Let this process, when `entry` runs it, end right after its atexit
    handlers: the teardown after them (each module's objects freed one by
    one, the interned strings, the last collection) frees memory the exit
    frees anyway, 0.05-0.1 s of a process that loaded a soa step (numba's
    objects). A command calls it once its output is written and closed."""
    _TEARDOWN_SKIPPABLE.append(True)


def entry(argv: list[str] | None = None) -> int:
    """The `touchswarm` console script: main(argv), whose status the
    process exits with, after a command that called skip_teardown without
    the interpreter's teardown. Tests and other callers in process call
    main, which neither ends the process nor sets its environment."""
    import atexit
    # one BLAS thread unless the user asked for more: a command's matrix
    # products are perception's small ones, which OpenBLAS runs in one
    # thread anyway, while starting its pool when numpy is imported costs
    # 0.05-0.07 s of a command's start (`python -c "import numpy"`: 0.19 ->
    # 0.12 s on 2 cores); its child processes (a sweep's) inherit it
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    status: list[int] = []
    # registered before any other handler, so it runs after every one of
    # them (and after the non-daemon threads were joined: the exit's order)
    atexit.register(_end_now, status)
    rc = main(argv)
    if _TEARDOWN_SKIPPABLE and isinstance(rc, int) and not isinstance(rc, bool):
        status.append(rc)
    return rc


def _end_now(status: list[int]) -> None:
    if not status:
        return
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):        # a closed pipe: the interpreter's exit reports it
        return
    os._exit(status[0])


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
    if argv == ["--version"]:
        # the whole command line: nothing to parse, so no parser to build
        from sim_backend.version import version
        print(f"touchswarm {version()}")
        raise SystemExit(EXIT_OK)
    from bridge.cli_parser import build_parser
    parser = build_parser()
    args = parser.parse_args(argv)
    # a command may set quiet_logging: it configures logging itself on the
    # paths whose modules log, so its plain path imports no logging
    if args.verbose or not getattr(args, "quiet_logging", False):
        configure_logging(args.verbose)
    if not getattr(args, "func", None):
        parser.print_help()
        return EXIT_USAGE
    from bridge.errors import BridgeError, UsageError
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
    except Exception as err:
        # a bug in the user's own behaviour (its step, its coordinator) while
        # it ran: one line naming its file and line (-vv logs the traceback);
        # anything else is ours, and its traceback is the report
        own = registry.failed_in(err)
        if own is None:
            raise
        import logging
        logging.getLogger("touchswarm").debug("the behaviour's error", exc_info=True)
        print(f"touchswarm: error: {own} (touchswarm -vv: the traceback)", file=sys.stderr)
        return EXIT_FAILED


if __name__ == "__main__":
    sys.exit(main())
