"""`touchswarm scenarios`: list the built-in scenarios and their keys."""

from __future__ import annotations

import argparse


def register(sub) -> None:
    p = sub.add_parser("scenarios", help="list built-in scenarios and the scenario keys",
                       description="List the built-in scenarios, then every scenario key "
                                   "with its default and allowed range.")
    p.set_defaults(func=cmd_scenarios)


def cmd_scenarios(args: argparse.Namespace) -> int:
    from sim_backend import scenario
    for name in scenario.builtin_names():
        sc = scenario.load(name)
        print(f"{name:10s} {sc.description}")
    print("\nkeys (default, allowed):")
    base = scenario.Scenario()
    for key, value in base.to_dict().items():
        rng = scenario.RANGES.get(key)
        if key in scenario.CHOICES_ALL:
            print(f"  {key:16s} {value!s:10s} {' | '.join(scenario.CHOICES_ALL[key])}")
            continue
        allowed = f"{rng[1]}..{rng[2]}" if rng else {
            "movementModel": " | ".join(scenario.MODELS),
            "breeds": "[[breeds]] tables: count, name, " + ", ".join(scenario.BREED_KEYS),
            "object": "1-4 | " + " | ".join(
                sorted(__import__('sim_backend.objects', fromlist=['x']).SHAPES)),
            "objects": "[[objects]] tables (docs/scenarios.md)",
            "obstacles": "[[obstacles]] tables (docs/scenarios.md)",
            "field": "static | dynamic",
            "crowd": "block | yield",
            "wrap": "false | true",
            "recognise": "true | false (confidence: the posterior it needs)",
        }.get(key, "text")
        print(f"  {key:16s} {value!s:10s} {allowed}")
    from sim_backend import objects
    print("\nshapes (object = NAME, or shape = NAME in [[objects]]; rows top to bottom):")
    for name in sorted(objects.SHAPES):
        print(f"  {name}:")
        for row in objects.art(name).split("\n"):
            print(f"    {row}")
    return 0
