"""`touchswarm deploy --port PORT`: put the robot firmware and a behaviour on a
MicroPython board."""

from __future__ import annotations

import argparse

from bridge.errors import UsageError

EPILOG = """examples:
  touchswarm deploy --port /dev/ttyACM0 --config NODE=3
  touchswarm deploy --port /dev/ttyACM0 --behaviour ./mine --set quietTicks=60 --config NODE=2
The board gets the firmware core as firmware_logic/, the behaviour's board-side
modules as the package behaviour/ (its relative imports work there) and
robot_config.py with ARGS, the robot's constructor arguments computed here by the
behaviour's robot_args for NODE, SEED and the scenario."""


def register(sub) -> None:
    from bridge.serial.deploy import CONFIG_KEYS
    p = sub.add_parser(
        "deploy",
        description="Run the subset check, compile the firmware and the behaviour with "
                    "mpy-cross, copy them with mpremote, verify every file on the device by "
                    "sha256, then import the behaviour on the device and build its robot as "
                    "main.py does, and print the bytes deployed. Refuses firmware failing the "
                    "subset check and a device whose .mpy version differs from mpy-cross's.",
        epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--port", required=True, metavar="PORT",
                   help="device path (/dev/ttyACM0) or any pyserial URL (rfc2217://host:port)")
    p.add_argument("--config", action="append", default=[], metavar="KEY=N",
                   help="robot_config.py keys %s (repeatable; NODE and SEED default to 1); "
                        "the behaviour's own parameters go with --set" % ", ".join(CONFIG_KEYS))
    p.add_argument("--behaviour", default=None, metavar="NAME|FOLDER",
                   help="the behaviour the board runs: a name (`touchswarm behaviours`) or a "
                        "folder (default: the scenario's, thesis)")
    p.add_argument("--scenario", default=None, metavar="NAME|FILE",
                   help="the scenario the robot's arguments are read off (default: the "
                        "behaviour's defaults)")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key, e.g. the behaviour's own parameters "
                        "(repeatable)")
    p.add_argument("--mpy-cross", metavar="PATH", help="mpy-cross to use (default: on PATH)")
    p.add_argument("--mpremote", metavar="PATH", help="mpremote to use (default: on PATH)")
    p.add_argument("--start", action="store_true",
                   help="start the firmware after deploying (mpremote exec --no-follow)")
    p.set_defaults(func=cmd_deploy)


def parse_config(items: list[str]) -> dict[str, int]:
    from bridge.serial.deploy import CONFIG_KEYS
    out: dict[str, int] = {}
    for item in items:
        key, eq, value = item.partition("=")
        key = key.strip().upper()
        if not eq or key not in CONFIG_KEYS:
            raise UsageError("--config %r: expected KEY=N with KEY one of %s (the behaviour's "
                             "parameters go with --set KEY=VALUE)"
                             % (item, ", ".join(CONFIG_KEYS)))
        try:
            out[key] = int(value)
        except ValueError:
            raise UsageError("--config %s=%r: the value must be an integer" % (key, value)) \
                from None
        lo, hi = _config_range(key)
        if not lo <= out[key] <= hi:
            raise UsageError(f"--config {key}={out[key]}: expected {lo}..{hi}")
    return out


def _config_range(key: str) -> tuple[int, int]:
    """The allowed values of a robot_config key, from where each is defined."""
    from firmware_logic.messages import MAX_NODE
    from sim_backend.scenario import SEED_MAX, SEED_MIN
    if key == "NODE":
        return 1, MAX_NODE
    if key == "SEED":
        return SEED_MIN, SEED_MAX
    return 0, 2 ** 31 - 1      # the board's own checks bound the rest


def _check_tool(option: str, path: str | None) -> None:
    """A tool given by path must exist and be executable, or mpremote's and
    the OS's words would name neither the option nor the fix."""
    import os
    if path is None:
        return
    if not os.path.exists(path):
        raise UsageError(f"{option} {path}: no such file")
    if os.path.isdir(path) or not os.access(path, os.X_OK):
        raise UsageError(f"{option} {path}: not an executable program")


def deploy_scenario(args: argparse.Namespace):
    """The scenario of --scenario, --set and --behaviour; None when none of
    them is given (the behaviour's defaults, or the device's kept config)."""
    from bridge.commands.run import parse_overrides
    from sim_backend import scenario
    if args.scenario is None and not args.set:
        return None
    sc = scenario.load(args.scenario or "default")
    changes = parse_overrides(args.set)
    if args.behaviour is not None:
        if "behaviour" in changes and str(changes["behaviour"]) != args.behaviour:
            raise UsageError(f"--behaviour {args.behaviour} and --set behaviour="
                             f"{changes['behaviour']} disagree; give one of them")
        changes["behaviour"] = args.behaviour
    return sc.replace(**changes) if changes else sc


def cmd_deploy(args: argparse.Namespace) -> int:
    from bridge import devices
    from bridge.serial.deploy import DeployError, Deployer
    why = devices.missing(args.port)
    if why:
        # mpremote would say "may be in use by another program"
        raise UsageError(f"--port {args.port}: {why}")
    config = parse_config(args.config)
    _check_tool("--mpy-cross", args.mpy_cross)
    _check_tool("--mpremote", args.mpremote)
    from sim_backend import registry
    if args.behaviour is not None:
        try:
            # its robot module too: a file that fails here fails on the board,
            # so refuse before anything is copied
            registry.load(args.behaviour).robot_class
        except registry.BehaviourError as err:
            raise UsageError(f"--behaviour: {err}") from None
    sc = deploy_scenario(args)
    behaviour = args.behaviour if args.behaviour is not None else \
        (str(sc.behaviour) if sc is not None else "thesis")
    d = Deployer(args.port, mpy_cross=args.mpy_cross, mpremote=args.mpremote,
                 behaviour=behaviour)
    try:
        # the robot's arguments on the host, before the board is touched: a
        # robot_args that fails is the behaviour's mistake, not the board's
        d.robot_config(config, sc)
    except DeployError as err:
        raise UsageError(str(err)) from None
    report = d.deploy(config if config or sc is not None else None, sc)
    for f in report.files:
        print("%-34s %6d bytes  sha256 %s  verified" % (f.remote, f.size, f.sha256[:16]))
    print("deployed %d bytes in %d files to %s (.mpy v%s)"
          % (report.total_bytes, len(report.files), args.port, report.mpy_version))
    if report.kept_config is not None:
        kept = ", ".join(line.replace(" ", "") for line in report.kept_config.splitlines()
                         if "=" in line)
        print("kept the device's robot_config.py from an earlier deploy (%s); pass --config "
              "KEY=N to replace it" % (kept or "empty"))
    print(report.imported)
    if args.start:
        d.start()
        print("firmware started")
    return 0
