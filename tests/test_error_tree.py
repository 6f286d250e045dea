"""One small error tree per package: every exception class sim_backend
defines is a SimError, every one bridge defines a BridgeError (the CLI turns
each root into one line and an exit code, bridge/cli.py), except the few
that never leave their module (control flow between two functions)."""

from __future__ import annotations

import importlib
import pkgutil

import pytest

from bridge.errors import BridgeError
from sim_backend.errors import SimError

ROOTS = {"sim_backend": SimError, "bridge": BridgeError}
# caught in the module that raises them; never reach a caller
INTERNAL = {"bridge.record.replay.Diverged", "bridge.behaviour_check.StepFailed",
            "bridge.behaviour_check.NotRun", "bridge.view.sources.BadRequest"}


def exceptions(package: str) -> dict[str, type]:
    """Every exception class the package's modules define, by full name."""
    pkg = importlib.import_module(package)
    out = {}
    for info in [None, *pkgutil.walk_packages(pkg.__path__, package + ".")]:
        name = package if info is None else info.name
        for attr, value in vars(importlib.import_module(name)).items():
            if isinstance(value, type) and issubclass(value, BaseException) \
                    and value.__module__ == name:
                out[f"{name}.{attr}"] = value
    return out


@pytest.mark.parametrize("package", sorted(ROOTS))
def test_every_error_is_under_the_package_root(package: str) -> None:
    found = exceptions(package)
    assert found
    stray = sorted(n for n, cls in found.items()
                   if not issubclass(cls, ROOTS[package]) and n not in INTERNAL)
    assert stray == []
