"""`touchswarm firmware check`: the subset check plus the MicroPython conformance run.

Registered by bridge/cli.py (COMMANDS); can also be run alone as
`python -m bridge.firmware.cli check`.
"""

from __future__ import annotations

import argparse
import json
import sys


def register(sub: argparse._SubParsersAction) -> argparse.ArgumentParser:  # type: ignore[type-arg]
    p = sub.add_parser(
        "firmware",
        description="Tools for the robot firmware in firmware_logic/.")
    fsub = p.add_subparsers(dest="firmware_command", metavar="SUBCOMMAND")
    c = fsub.add_parser(
        "check", help="subset check, mpy-cross, CPython/MicroPython traces, heap",
        description="Check the firmware core (firmware_logic/*.py) and a behaviour's folder "
                    "against the MicroPython subset rules (docs/subset.md), compile them with "
                    "mpy-cross as a board holds them, run the same seeded scripted robot under "
                    "CPython and MicroPython for each movement model and compare the traces, "
                    "and measure heap bytes per step. The script sends every down message the "
                    "behaviour declares; every state in its STATES must be visited (a FAIL "
                    "line names each one never reached). The robot is built from the "
                    "behaviour's robot_args over the scenario (--scenario, --set). Exit status "
                    "0 only if everything passes.",
        epilog="examples:\n"
               "  touchswarm firmware check\n"
               "  touchswarm firmware check --behaviour ./my_behaviours/disperse\n"
               "  touchswarm firmware check --behaviour aggregate --scenario my.toml --ticks 1500",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    c.add_argument("--json", action="store_true", help="print one JSON object")
    c.add_argument("--behaviour", default=None, metavar="NAME|FOLDER",
                   help="behaviour to check: a name from `touchswarm behaviours` or a folder "
                        "anywhere (default: the scenario's, thesis)")
    c.add_argument("--scenario", default="default", metavar="NAME|FILE",
                   help="the scenario the robot's arguments are read off (default: "
                        "%(default)s)")
    c.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key, e.g. the behaviour's own parameters "
                        "(repeatable)")
    c.add_argument("--seed", type=int, default=12345, help="run seed (default: %(default)s)")
    c.add_argument("--node", type=int, default=3, help="robot node id (default: %(default)s)")
    c.add_argument("--ticks", type=int, default=2000,
                   help="ticks per conformance run (default: %(default)s)")
    c.set_defaults(func=cmd_check)
    p.set_defaults(func=lambda args: _help(p))
    return p


def _help(p: argparse.ArgumentParser) -> int:
    p.print_help()
    return 2


def check_scenario(args: argparse.Namespace):
    """The scenario of --scenario, --set and --behaviour, validated."""
    from bridge.commands.run import parse_overrides
    from bridge.errors import UsageError
    from sim_backend import scenario

    scenario.check_seed(args.seed, "--seed")
    sc = scenario.load(getattr(args, "scenario", "default"))
    changes = parse_overrides(getattr(args, "set", []))
    ref = getattr(args, "behaviour", None)
    if ref is not None:
        if "behaviour" in changes and str(changes["behaviour"]) != str(ref):
            raise UsageError(f"--behaviour {ref} and --set behaviour={changes['behaviour']} "
                             "disagree; give one of them")
        changes["behaviour"] = str(ref)
    return sc.replace(**changes) if changes else sc


def cmd_check(args: argparse.Namespace) -> int:
    from bridge.firmware.conformance import RunParams, run_conformance
    from bridge.firmware.subset_check import check_package, check_paths, package_dir

    from sim_backend import registry

    sc = check_scenario(args)
    b = registry.load(str(sc.behaviour)).activate()   # its message kinds in use
    b.robot_args(args.node, args.seed, sc)     # one line when they do not fit the FSM
    violations = check_package()
    if not b.folder.is_relative_to(package_dir()):
        violations = sorted(violations + check_paths([b.folder]))
    params = RunParams(node=args.node, seed=args.seed, ticks=args.ticks, behaviour=b.ref,
                       scenario=sc)
    rep = run_conformance(params=params, heap_steps=args.ticks)
    ok = not violations and rep.ok

    if getattr(args, "json", False):
        out = rep.as_dict()
        out["subset_violations"] = [v.as_dict() for v in violations]
        out["conformance_ok"] = rep.ok
        out["ok"] = ok
        print(json.dumps(out, indent=2, default=str))
        return 0 if ok else 1

    for v in violations:
        print(v)
    print("subset check: %d violation%s" % (len(violations), "" if len(violations) == 1 else "s"))
    if rep.mpy_cross_version:
        print("mpy-cross: %s" % rep.mpy_cross_version)
    if rep.micropython_version:
        print("micropython %s loads mpy v%s" % (rep.micropython_version, rep.mpy_version_port))
    if rep.mpy_sizes:
        print(".mpy sizes (bytes):")
        width = max(len(m) for m in rep.mpy_sizes)
        for mod, size in rep.mpy_sizes.items():
            print("  %-*s %6d" % (width, mod, size))
        print("  %-*s %6d" % (width, "total", rep.mpy_total))
        print("loaded from: %s" % ("the .mpy files" if rep.loaded_from == "mpy"
                                   else "the .py sources (the .mpy files did not load)"))
    for m in rep.models:
        if m.identical:
            trace = "traces identical (%d actions, %d trace lines)" % (m.actions, m.trace_lines)
        elif m.divergence is not None:
            trace = "traces DIVERGE at %s" % m.divergence
        else:
            trace = "no trace"
        print("%s: %s" % (m.model, trace))
        print("  robot: %s%r" % (b.robot_class.__name__, tuple(m.robot_args)))
        print("  states visited: %s" % (" ".join(m.states_visited) or "-"))
        if m.heap_steps:
            print("  heap: %d bytes over %d steps = %.2f bytes/step; under heap_lock: %s"
                  % (m.heap_bytes, m.heap_steps, m.heap_per_step,
                     "no allocation" if m.heap_locked_ok
                     else "MemoryError at step %d" % m.heap_locked_failed_step))
    if rep.down_messages:
        print("down messages the script sent: %s" % ", ".join(rep.down_messages))
    for e in rep.errors:
        print("error: %s" % e, file=sys.stderr)
    for state, where in rep.unvisited().items():
        print("FAIL: state %r was never reached under MicroPython (%s)"
              % (state, ", ".join(where)))
    print("firmware check: %s" % ("PASS" if ok else "FAIL"))
    return 0 if ok else 1


def main(argv: list[str] | None = None) -> int:
    """`python -m bridge.firmware.cli ARGS` is `touchswarm firmware ARGS`."""
    from bridge.cli import main as cli_main
    return cli_main(["firmware", *(sys.argv[1:] if argv is None else argv)])


if __name__ == "__main__":
    sys.exit(main())
