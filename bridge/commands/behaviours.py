"""`touchswarm behaviours`: what is installed; `touchswarm behaviour new NAME`:
a scaffold that passes `firmware check` and runs in simulation."""

from __future__ import annotations

import argparse
import keyword
from pathlib import Path

from bridge.commands.paths import path_arg
from bridge.errors import UsageError

EPILOG = """examples:
  touchswarm behaviours                      # name, states, models, where
  touchswarm behaviour new swarmchain        # firmware_logic/behaviours/swarmchain/
  touchswarm behaviour new mine --into ./my_behaviours
  touchswarm firmware check --behaviour swarmchain
guide: docs/writing-a-behaviour.md"""


def register(sub) -> None:
    p = sub.add_parser("behaviours", help="list the installed behaviours",
                       description="List every behaviour the registry finds: the built-ins "
                                   "and those other packages add through the entry point "
                                   "group 'touchswarm.behaviours'.",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.set_defaults(func=cmd_list)
    n = sub.add_parser("behaviour", help="make a new behaviour from a scaffold",
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
    n.set_defaults(func=lambda args: (n.print_help(), 2)[1])


def cmd_list(args: argparse.Namespace) -> int:
    from firmware_logic import registry

    for name, module in sorted(registry.names().items()):
        try:
            b = registry.load(name)
        except registry.BehaviourError as err:
            print(f"{name:12s} BROKEN: {err}")
            continue
        print(f"{name:12s} {b.spec.TITLE}")
        print(f"{'':12s} states: {', '.join(b.spec.STATES)}; models: "
              f"{', '.join(n for _, n in b.spec.MODELS)}; module {module}")
    return 0


def cmd_new(args: argparse.Namespace) -> int:
    from firmware_logic import registry

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
    package = f"firmware_logic.behaviours.{name}" if inside else name
    dest.mkdir()
    for src in template.modules():
        text = src.read_text()
        text = text.replace("firmware_logic.behaviours.aggregate", package)
        text = text.replace('NAME = "aggregate"', f'NAME = "{name}"')
        (dest / src.name).write_text(text)
    print(f"created {dest}/ ({', '.join(p.name for p in sorted(dest.glob('*.py')))})")
    print(f"use it as --behaviour {name if inside else dest}; guide: "
          "docs/writing-a-behaviour.md")
    return 0


