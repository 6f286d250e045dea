"""`touchswarm deploy --port PORT`: put the robot firmware on a MicroPython board."""

from __future__ import annotations

import argparse

from bridge.errors import UsageError

CONFIG_KEYS = ("NODE", "SEED", "MODEL", "SPAN", "DEFIANCE", "POWER", "MAX_TICKS", "LINGER",
               "HEAP_CHECK")


def register(sub) -> None:
    p = sub.add_parser(
        "deploy", help="check, compile and copy the robot firmware to a MicroPython board",
        description="Run the subset check, compile the firmware with mpy-cross, copy it with "
                    "mpremote, verify every file on the device by sha256 and print the bytes "
                    "deployed. Refuses firmware failing the subset check and a device whose "
                    ".mpy version differs from mpy-cross's.")
    p.add_argument("--port", required=True, metavar="PORT",
                   help="device path (/dev/ttyACM0) or any pyserial URL (rfc2217://host:port)")
    p.add_argument("--config", action="append", default=[], metavar="KEY=N",
                   help="write robot_config.py on the device, keys %s (repeatable)"
                        % ", ".join(CONFIG_KEYS))
    p.add_argument("--behaviour", default="thesis", metavar="NAME",
                   help="the behaviour the board runs (a built-in one, `touchswarm "
                        "behaviours`; default: thesis); written into robot_config.py")
    p.add_argument("--mpy-cross", metavar="PATH", help="mpy-cross to use (default: on PATH)")
    p.add_argument("--mpremote", metavar="PATH", help="mpremote to use (default: on PATH)")
    p.add_argument("--start", action="store_true",
                   help="start the firmware after deploying (mpremote exec --no-follow)")
    p.set_defaults(func=cmd_deploy)


def parse_config(items: list[str]) -> dict[str, int]:
    out: dict[str, int] = {}
    for item in items:
        key, eq, value = item.partition("=")
        key = key.strip().upper()
        if not eq or key not in CONFIG_KEYS:
            raise UsageError("--config %r: expected KEY=N with KEY one of %s"
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


def cmd_deploy(args: argparse.Namespace) -> int:
    from bridge import devices
    from bridge.serial.deploy import Deployer
    from firmware_logic import registry
    why = devices.missing(args.port)
    if why:
        # mpremote would say "may be in use by another program"
        raise UsageError(f"--port {args.port}: {why}")
    config: dict[str, int | str] = dict(parse_config(args.config))
    _check_tool("--mpy-cross", args.mpy_cross)
    _check_tool("--mpremote", args.mpremote)
    try:
        behaviour = registry.load(args.behaviour)
    except registry.BehaviourError as err:
        raise UsageError(f"--behaviour: {err}") from None
    if behaviour.name != "thesis":
        # main.py runs the thesis unless robot_config.py names another behaviour
        config["BEHAVIOUR"] = behaviour.module_name
    d = Deployer(args.port, mpy_cross=args.mpy_cross, mpremote=args.mpremote,
                 behaviour=behaviour.name)
    report = d.deploy(config or None)
    for f in report.files:
        print("%-34s %6d bytes  sha256 %s  verified" % (f.remote, f.size, f.sha256[:16]))
    print("deployed %d bytes in %d files to %s (.mpy v%s)"
          % (report.total_bytes, len(report.files), args.port, report.mpy_version))
    if report.kept_config is not None:
        kept = ", ".join(line.replace(" ", "") for line in report.kept_config.splitlines()
                         if "=" in line)
        print("kept the device's robot_config.py from an earlier deploy (%s); pass --config "
              "KEY=N to replace it" % (kept or "empty"))
    if args.start:
        d.start()
        print("firmware started")
    return 0
