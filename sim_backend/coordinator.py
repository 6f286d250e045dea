"""The coordinator contract as types: what every behaviour's coordinator
offers the engines, and the abilities a coordinator may add, each declared
once here instead of asked for by name (`hasattr`) where it is used.

A behaviour's coordinator lives in its folder (firmware-subset code, see
firmware_logic/roster.py for the host contract its base class Roster
implements); these protocols only describe it, so a coordinator needs no
import of this module to meet them. Each ability is a runtime-checkable
protocol: `isinstance(c, Measuring)` says whether `c` has it.
"""

from __future__ import annotations

import functools
from typing import Any, Protocol, runtime_checkable


@runtime_checkable
class Coordinator(Protocol):
    """What an engine asks of every coordinator (sim_backend/engine.py)."""

    touches: Any            # the accepted touches, each with node, tick, rx, ry
    delivered_tick: int     # -1 until the object is home

    def on_message(self, node: int, kind: int, fields: Any, tick: int) -> None: ...

    def tick(self, t: int) -> list: ...

    def status(self) -> str: ...


@runtime_checkable
class HostCoordinator(Coordinator, Protocol):
    """What the host process relies on besides (the host contract,
    firmware_logic/roster.py; Roster has all of it)."""

    nodes: dict
    rejected: dict

    def replay(self, node: int, kind: int, fields: Any, tick: int) -> None: ...

    def snapshot(self) -> dict: ...

    def adopt(self, state: dict) -> None: ...

    def decision(self, before: dict, out: list) -> Any: ...

    def done(self) -> bool: ...

    def carriers(self) -> Any: ...

    def quiet(self) -> bool: ...


@runtime_checkable
class Muted(Protocol):
    """Ability: declares, at each tick(), the messages that would change
    nothing until its next tick(), so an engine does not hand them over
    (sim_backend/exchange.py `muting`, the one rule `Muting.drops`):
    muted() -> (kind, nodes, but) or (kind, nodes, but, same), or None.
    Dropped: the messages of `kind` from the nodes in `nodes` (a collection
    that only grows) other than node `but`, and `but`'s whose fields are
    `same` (an unchanged repeat: the thesis's transport leader reporting
    the pose it reported last) until a message of `kind` from `but` with
    other fields is handed over. A message handed over in between never
    makes a muted one count."""

    def muted(self) -> Any: ...


@runtime_checkable
class Idling(Protocol):
    """Ability: says when it next needs tick() though it hears nothing:
    idle_until() -> the first tick t at which tick(t) may change anything
    or send when no message is handed over before it (0: any tick), read
    from its state as it is now. A batch engine asks it to tick() only
    when it heard a message or that tick has come (`exchange.wake`; a
    `quiet()` coordinator is never asked); without the ability, every tick.
    tests/test_muted_messages.py checks both promises on whole runs."""

    def idle_until(self) -> int: ...


@runtime_checkable
class Measuring(Protocol):
    """Ability: the behaviour's own end-of-run measures (summary.json)."""

    def measures(self) -> dict: ...


@runtime_checkable
class Segmenting(Protocol):
    """Ability: the touched cells as they are now (the host's perceived shape)."""

    def segments_now(self) -> Any: ...


@runtime_checkable
class Tracking(Protocol):
    """Ability: the touched segments of an object the coordinator tracks as it
    moves (touches with sx, sy; the displacement since), as the thesis's does."""

    touches: Any
    moved_x: int
    moved_y: int


@runtime_checkable
class Recognising(Protocol):
    """Ability: judges touched clusters with the host's decider
    (perception/decide.py): asks for one (`wants_decider()`, answered by
    `equip`) and holds it as `decider` (None until given), as the thesis's
    does; the permille a verdict needs is the behaviour's own parameter."""

    decider: Any

    def wants_decider(self) -> bool: ...


@runtime_checkable
class Ending(Protocol):
    """Ability: says how the mission ended (firmware_logic/roster.py OUTCOMES:
    delivered, halted, stalled), "" while it goes on; Roster has it."""

    def ended(self) -> str: ...


@runtime_checkable
class TruthMeasuring(Protocol):
    """Ability: measures that need the truth a coordinator is never told (the
    target's cells), given to it by an in-process engine at the end."""

    def truth_measures(self, target: set) -> dict: ...


# (coordinator class, ability) -> the ability's data members the class does
# not carry itself (a field from __init__: looked up on each instance), or
# None when a method is among them (isinstance decides); see `has`
_HAS: dict[tuple[type, type], tuple[str, ...] | None] = {}


def has(c: Any, ability: type) -> bool:
    """isinstance(c, ability), with what the coordinator's class carries (its
    methods) decided once per class: a runtime-checkable protocol's
    isinstance looks every member up by name each time, about 30 us for one
    with data members, and a batch asks several per run. A member set on
    the instance (a field from __init__, a test's SimpleNamespace fake) may
    differ between instances of one class, so those are asked each time;
    when one is missing, isinstance decides (a class may still subclass or
    be registered with the protocol)."""
    key = (type(c), ability)
    try:
        own = _HAS[key]
    except KeyError:
        own = _HAS[key] = _instance_members(type(c), ability)
    if own is not None:
        for m in own:
            if not hasattr(c, m):
                break
        else:
            return True
    return isinstance(c, ability)


def _instance_members(cls: type, ability: type) -> tuple[str, ...] | None:
    """The data members of `ability` that `cls` lacks; None when it lacks a
    method (isinstance also refuses a method set to None on the instance)."""
    out = tuple(m for m in members(ability) if not hasattr(cls, m))
    if any(callable(getattr(ability, m, None)) for m in out):
        return None
    return out


def measures_of(c: Any) -> dict:
    """The coordinator's own measures; none when it declares no such ability."""
    return c.measures() if has(c, Measuring) else {}


@functools.cache
def members(contract: type) -> tuple[str, ...]:
    """The names a protocol above declares, its bases' included (a
    protocol's members do not change, and `has` asks per run)."""
    out: list[str] = []
    for cls in reversed(contract.__mro__):
        if getattr(cls, "_is_protocol", False) and cls is not Protocol:
            out += list(vars(cls).get("__annotations__", {}))
            out += [m for m, v in vars(cls).items() if callable(v) and not m.startswith("_")]
    return tuple(dict.fromkeys(out))


def lacks(c: Any, contract: type) -> list[str]:
    """The members of `contract` that `c` lacks, by name (for an error that
    says what to add); empty when `c` meets it."""
    return [m for m in members(contract) if not hasattr(c, m)]
