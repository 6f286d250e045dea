"""`touchswarm behaviours`: what is installed; `touchswarm behaviour new NAME`:
a scaffold that passes `firmware check` and runs in simulation."""

from __future__ import annotations

import argparse
import keyword

from bridge.behaviour_check import STEPS
from bridge.commands.numbers import count
from bridge.commands.paths import path_arg
from bridge.errors import UsageError

EPILOG = """examples:
  touchswarm behaviours                      # name, states, models, where
  touchswarm behaviour new swarmchain        # firmware_logic/behaviours/swarmchain/
  touchswarm behaviour new mine --into ./my_behaviours
  touchswarm firmware check --behaviour swarmchain
guide: docs/writing-a-behaviour.md"""


def register(sub) -> None:
    p = sub.add_parser("behaviours",
                       description="List every behaviour the registry finds: the built-ins "
                                   "and those other packages add through the entry point "
                                   "group 'touchswarm.behaviours'.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.set_defaults(func=cmd_list)
    n = sub.add_parser("behaviour",
                       description="Create a behaviour package (spec.py, robot.py, "
                                   "coordinator.py, __init__.py) from the aggregation "
                                   "behaviour, renamed, ready to edit.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    nsub = n.add_subparsers(dest="action", metavar="ACTION")
    new = nsub.add_parser("new", help="scaffold a behaviour package",
                          description="Copy the aggregation behaviour into a new package "
                                      "NAME and rename it; by default into "
                                      "firmware_logic/behaviours/ so that `firmware check` "
                                      "and `deploy` see it.")
    new.add_argument("name", help="a Python identifier, lower case (e.g. chain)")
    new.add_argument("--into", type=path_arg, default=None,
                     help="parent folder (default: firmware_logic/behaviours/)")
    new.set_defaults(func=cmd_new)
    chk = nsub.add_parser("check", help="run every step on a behaviour folder",
                          description="Run every step a behaviour must pass, as a user runs "
                                      "it: load, run, sweep (soa == reference), firmware "
                                      "check, run --link can --record + replay, dbc, robots + "
                                      "host over SLCAN on a pty, and with --port: deploy, and a "
                                      "mission with the board as robot 1. Prints "
                                      "a table of PASS/FAIL with the first error of each; exit "
                                      "1 when a step failed. A new behaviour's first sweep "
                                      "compiles its soa engine (1.5-3.5 min).")
    chk.add_argument("folder", type=path_arg, metavar="DIR|NAME",
                     help="the behaviour's folder (or an installed behaviour's name)")
    chk.add_argument("--ticks", type=count(1, what="ticks"), default=400, metavar="N",
                     help="ticks of each run (default 400)")
    chk.add_argument("--port", default=None, metavar="PORT",
                     help="a MicroPython board's serial port for the deploy and mission "
                          "steps")
    chk.add_argument("--only", action="append", default=[], metavar="STEP",
                     help=f"run only these steps (repeatable): {', '.join(STEPS)}")
    chk.set_defaults(func=cmd_check)
    n.set_defaults(func=lambda args: (n.print_help(), 2)[1])


def cmd_list(args: argparse.Namespace) -> int:
    from sim_backend import registry
    from sim_backend import studies

    for name, module in sorted(registry.names().items()):
        try:
            b = registry.load(name)
        except registry.BehaviourError as err:
            print(f"{name:12s} BROKEN: {err}")
            continue
        print(f"{name:12s} {b.spec.TITLE}")
        print(f"{'':12s} states: {', '.join(b.spec.STATES)}; models: "
              f"{', '.join(n for _, n in b.spec.MODELS)}; module {module}")
        if b.messages:
            print(f"{'':12s} own messages (kinds are per behaviour): "
                  + ", ".join(f"{m[1]} (kind {m[0]}, {m[2]})" for m in b.messages))
        try:
            own = ", ".join(studies.of(name))
        except studies.StudyError as err:
            own = f"BROKEN: {err}"
        if own:
            print(f"{'':12s} studies (touchswarm sweep --study NAME): {own}")
    return 0


def cmd_new(args: argparse.Namespace) -> int:
    from sim_backend import registry

    name = args.name
    if not name.isidentifier() or keyword.iskeyword(name) or name != name.lower():
        raise UsageError(f"behaviour name {name!r}: use a lower-case Python identifier")
    if name in registry.names():
        raise UsageError(f"behaviour {name!r} exists already; pick another name")
    template = registry.load("aggregate")
    parent = args.into if args.into is not None else template.folder.parent
    if not parent.is_dir():
        raise UsageError(f"--into {str(parent)!r}: no such folder")
    dest = parent / name
    if dest.exists():
        raise UsageError(f"{str(dest)!r} exists already")
    inside = parent.resolve() == template.folder.parent.resolve()
    # the template imports its own modules relatively (docs/writing-a-behaviour.md,
    # "Imports"), so the copy works under any name and folder: only NAME changes
    texts = {src.name: src.read_text() for src in template.modules()}
    if texts["spec.py"].count('NAME = "aggregate"') != 1:
        raise UsageError(f"the template {template.folder}/spec.py has no line "
                         'NAME = "aggregate"')
    texts["spec.py"] = texts["spec.py"].replace('NAME = "aggregate"', f'NAME = "{name}"')
    dest.mkdir()
    for file, text in texts.items():
        (dest / file).write_text(text)
    print(f"created {dest}/ ({', '.join(p.name for p in sorted(dest.glob('*.py')))})")
    # a relative folder as ./NAME: a bare NAME reads as an installed behaviour's
    where = dest if dest.is_absolute() or str(dest).startswith(".") else f"./{dest}"
    print(f"use it as --behaviour {name if inside else where}; guide: "
          "docs/writing-a-behaviour.md")
    return 0




def cmd_check(args: argparse.Namespace) -> int:
    from bridge import behaviour_check as bc
    from sim_backend import registry

    folder = args.folder
    if not folder.exists():
        known = registry.names()
        if str(folder) not in known:
            raise UsageError(f"behaviour {str(folder)!r}: no such folder nor an installed "
                             f"behaviour ({', '.join(sorted(known))})")
        folder = registry.load(str(folder)).folder
    elif not folder.is_dir():
        raise UsageError(f"behaviour {str(folder)!r}: a file; give the behaviour's folder "
                         f"({folder.parent})")
    bad = [s for s in args.only if s not in bc.STEPS]
    if bad:
        raise UsageError(f"--only {bad[0]!r}: expected one of {', '.join(bc.STEPS)}")
    steps = tuple(s for s in bc.STEPS if not args.only or s in args.only)
    print(f"checking {folder} ({len(steps)} steps)")

    def line(o) -> None:
        print(f"  {o.step:9s} {o.status:8s} {o.seconds:6.1f} s  {o.detail}", flush=True)

    out = bc.check(folder, ticks=args.ticks, port=args.port, steps=steps, on_step=line)
    failed = [o.step for o in out if o.status == "FAIL"]
    print(f"behaviour check: {'FAIL (' + ', '.join(failed) + ')' if failed else 'PASS'}")
    return 1 if failed else 0
