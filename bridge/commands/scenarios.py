"""`touchswarm scenarios`: list the built-in scenarios, the world's keys and
a behaviour's own keys."""

from __future__ import annotations

import argparse

EPILOG = """examples:
  touchswarm scenarios                          # built-ins, world keys, the thesis's keys
  touchswarm scenarios --behaviour aggregate    # that behaviour's own keys (spec.PARAMS)
                                                # and studies (studies.py)
  touchswarm scenarios --behaviour ./mine       # a behaviour folder's keys"""


def register(sub) -> None:
    p = sub.add_parser("scenarios",
                       description="List the built-in scenarios, then every key of the "
                                   "world with its default and allowed range, then the "
                                   "keys the behaviour declares (its spec.PARAMS) and its "
                                   "studies (its studies.py; `touchswarm sweep --study NAME`).",
                       epilog=EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--behaviour", default=None, metavar="NAME|DIR",
                   help="whose own keys to list (default: the default scenario's, thesis)")
    p.set_defaults(func=cmd_scenarios)


def cmd_scenarios(args: argparse.Namespace) -> int:
    from sim_backend import arena, objects, params, scenario, studies
    behaviour = args.behaviour or scenario.DEFAULT_BEHAVIOUR
    declared = params.declared(behaviour, scenario.WORLD_KEYS)   # ScenarioError: one line
    own = studies.of(behaviour)                                  # StudyError: one line
    for name in scenario.builtin_names():
        sc = scenario.load(name)
        print(f"{name:10s} {sc.description}")
    print("\nworld keys (default, allowed):")
    base = scenario.Scenario()
    for key in sorted(scenario.FIELDS, key=list(base.to_dict()).index):
        value = getattr(base, key)
        rng = scenario.RANGES.get(key)
        if key in scenario.CHOICES:
            allowed = " | ".join(scenario.CHOICES[key])
        elif rng:
            allowed = f"{rng[1]}..{rng[2]}"
        else:
            allowed = {
                "behaviour": "a name from `touchswarm behaviours`, or a folder",
                "breeds": "[[breeds]] tables: count, name and the behaviour's keys",
                "object": "1-4 | " + " | ".join(sorted(objects.SHAPES)),
                "objects": "[[objects]] tables (docs/scenarios.md)",
                "obstacles": "[[obstacles]] tables (docs/scenarios.md)",
                "field": " | ".join(arena.FIELD_MODES),
                "crowd": " | ".join(arena.CROWD_MODES),
                "wrap": "false | true",
            }.get(key, "text")
        print(f"  {key:16s} {value!s:10s} {allowed}")
    print(f"\nbehaviour {behaviour!r} keys (its spec.PARAMS; default, allowed, meaning):")
    for p in declared:
        default = str(p.default).lower() if p.kind == "bool" else p.default
        print(f"  {p.name:16s} {default!s:10s} {p.allowed():22s} {p.meaning}")
    print(f"\nbehaviour {behaviour!r} studies (its studies.py; touchswarm sweep --study NAME):")
    for st in own.values():
        print(f"  {st.name:16s} {len(st.points)} points x {st.seeds} seeds, until {st.until}; "
              f"{st.about}; figures: {', '.join(st.figure_names())}")
    if not own:
        print("  none (docs/writing-a-behaviour.md, \"Studies\")")
    print("\nshapes (object = NAME, or shape = NAME in [[objects]]; rows top to bottom):")
    for name in sorted(objects.SHAPES):
        print(f"  {name}:")
        for row in objects.art(name).split("\n"):
            print(f"    {row}")
    return 0
