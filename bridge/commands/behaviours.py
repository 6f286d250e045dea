"""`touchswarm behaviours`: what is installed; `touchswarm behaviour new NAME`:
a scaffold that passes `firmware check` and runs in simulation."""

from __future__ import annotations

import argparse
import ast
import keyword
import os
import re
import sysconfig
from pathlib import Path

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
                     help="parent folder (default: firmware_logic/behaviours/; refused "
                          "inside an installed package or where it cannot write)")
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
    _check_writable(parent, given=args.into is not None)
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
    texts = own_words(texts, name)
    dest.mkdir()
    for file, text in texts.items():
        (dest / file).write_text(text)
    print(f"created {dest}/ ({', '.join(p.name for p in sorted(dest.glob('*.py')))})")
    # a relative folder as ./NAME: a bare NAME reads as an installed behaviour's
    where = dest if dest.is_absolute() or str(dest).startswith(".") else f"./{dest}"
    print(f"use it as --behaviour {name if inside else where}; guide: "
          "docs/writing-a-behaviour.md")
    return 0




# the copy's own module docstrings: the template's describe the template.
# robot.py's keeps the template's line count, so the robot's code keeps its line
# numbers (the soa engine's compiled step is then the template's own)
DOCSTRINGS = {
    "spec.py": "{name}: its states, parameters, messages and measures, declared in one place.\n\n"
               "Made by `touchswarm behaviour new {name}`: its rules start as a copy of the\n"
               "aggregate behaviour's; say here what {name} does once you have changed them\n"
               "(docs/writing-a-behaviour.md).",
    "robot.py": "{name}'s robot: one `step(hal)` is one tick.\n\n"
                "All sensing happens before the tick's single movement request, as\n"
                "docs/tick-semantics.md requires; nothing allocates.",
    "coordinator.py": "{name}'s host side: fed the robots' decoded messages (node, kind, fields).\n\n"
                      "It keeps the run-facing attributes every engine, link and the host\n"
                      "process read (firmware_logic/roster.py, the host contract).",
    "__init__.py": "{name}: how the registry builds its robots and its coordinator.",
}
TITLE_LINE = re.compile(r"^TITLE = .*$", re.M)


def own_words(texts: dict[str, str], name: str) -> dict[str, str]:
    """The copied files with `name`'s own module docstrings and TITLE."""
    out = {}
    for file, text in texts.items():
        doc = DOCSTRINGS.get(file)
        body = ast.parse(text).body
        if doc is not None and body and isinstance(body[0], ast.Expr) \
                and isinstance(getattr(body[0], "value", None), ast.Constant) \
                and isinstance(body[0].value.value, str):
            lines = text.splitlines(keepends=True)
            first, last = body[0].lineno - 1, body[0].end_lineno or body[0].lineno
            doc = doc.format(name=name)
            doc = f'"""{doc}\n"""\n' if "\n" in doc else f'"""{doc}"""\n'
            text = "".join(lines[:first]) + doc + "".join(lines[last:])
        out[file] = text
    out["spec.py"] = TITLE_LINE.sub(
        f'TITLE = "{name}: a new behaviour; say here in one line what it does"',
        out["spec.py"], count=1)
    return out


def _check_writable(parent: Path, given: bool) -> None:
    """Refuse a folder of an installed package or one we cannot write: the
    behaviour would land where an upgrade deletes it, or nowhere."""
    where = f"--into {str(parent)!r}" if given else f"{parent} (the installed behaviours)"
    installed = {Path(p).resolve() for p in (sysconfig.get_paths()["purelib"],
                                              sysconfig.get_paths()["platlib"])}
    resolved = parent.resolve()
    if {"site-packages", "dist-packages"} & set(resolved.parts) \
            or any(resolved.is_relative_to(p) for p in installed):
        raise UsageError(f"{where}: inside an installed package (site-packages); "
                         "give --into DIR, a folder of your own")
    if not os.access(parent, os.W_OK):
        raise UsageError(f"{where}: not writable; give --into DIR, a folder of your own")


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
