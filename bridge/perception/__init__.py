"""Host-side incremental perception (issue 13): an evidence grid built from
touches and robot poses, a shape estimate with its uncertainty, and
recognition against a shape library. numpy is fine here; nothing in
firmware_logic imports this package (docs/perception.md).
"""

from typing import Any


def host_coordinator(behaviour: Any, sc: Any, **kw: Any) -> Any:
    """The behaviour's coordinator for scenario `sc` as every host runs it
    (the engines, the host process, replay): with `recognise`, equipped with
    the recogniser's decider (`decide.equip`), which is host code (numpy)
    the subset coordinator cannot import. kw: the registry's `coordinator`
    arguments (cells, journal, on_reject)."""
    c = behaviour.coordinator(sc, **kw)
    if getattr(sc, "recognise", False):
        from bridge.perception.decide import equip
        equip(c, sc)
    return c
