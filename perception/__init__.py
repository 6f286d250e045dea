"""Host-side incremental perception: an evidence grid built from
touches and robot poses, a shape estimate with its uncertainty, and
recognition against a shape library. numpy is fine here; nothing in
firmware_logic imports this package (docs/perception.md).
"""

import importlib
import sys
from typing import Any

DEBUG, INFO = 10, 20        # logging's levels, without importing it


def detail(name: str, level: int, msg: str, *args: Any) -> None:
    """Log a detail of the work (a recognition, a cluster's odds) at
    `level`, through `logging` only once something imported it: until then
    no handler is set up, and Python's last-resort handler drops records
    below WARNING anyway, so `touchswarm run` need not import logging
    (several M instructions of start-up) to drop them."""
    logging = sys.modules.get("logging")
    if logging is not None:
        logging.getLogger(name).log(level, msg, *args)


def host_coordinator(behaviour: Any, sc: Any, **kw: Any) -> Any:
    """The behaviour's coordinator for scenario `sc` as every host runs it
    (the engines, the host process, replay), equipped by the host libraries
    its package names in HOST_EQUIP (e.g. the recogniser's decider,
    `decide.equip`: host code, numpy, the subset coordinator cannot import).
    kw: the registry's `coordinator` arguments (cells, journal, on_reject)."""
    c = behaviour.coordinator(sc, **kw)
    for ref in getattr(behaviour.package, "HOST_EQUIP", ()):
        module, name = ref.split(":")
        getattr(importlib.import_module(module), name)(c, sc)
    return c
