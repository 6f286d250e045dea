"""The host's side of a tick boundary, one rule for both engines
(sim_backend/engine.py `Engine.exchange`, sim_backend/batch/soa.py
`SoaEngine._exchange`): the messages robots sent this tick go to the
coordinator's `on_message` in the order they were sent, except those it
declared `muted()` at its last `tick()` (they would change nothing:
tests/test_muted_messages.py); then it is asked to `tick()`, whose commands
go down to the robots. The batch engine asks only a coordinator that heard a
message or is not `quiet()`; the reference asks every tick.
"""

from __future__ import annotations

from typing import Any, Iterable, NamedTuple


class Muting(NamedTuple):
    """What a coordinator's muted() dropped when it was read: messages of
    `kind` from the nodes in `drop`; `key` tells a changed declaration."""
    kind: int
    drop: frozenset
    key: Any


HEARS_ALL = Muting(-1, frozenset(), None)


def muting(c: Any, prev: Muting | None = None) -> Muting:
    """c.muted(): (kind, nodes, but), the messages of that kind from the
    nodes in `nodes` (a collection that only grows) other than `but` change
    nothing until c's next tick(); a coordinator without `muted` (or
    returning None) hears every message. `prev` is kept while the
    declaration is the same (the same kind, collection, size and `but`)."""
    m = getattr(c, "muted", None)
    m = m() if m is not None else None
    if m is None:
        return HEARS_ALL
    kind, nodes, but = m
    key = (kind, id(nodes), len(nodes), but)
    if prev is not None and prev.key == key:
        return prev
    return Muting(kind, frozenset(nodes) - {but}, key)


def quiet(c: Any) -> bool:
    """c.quiet(): tick() without a new message would change nothing (a
    coordinator without `quiet` is never quiet)."""
    q = getattr(c, "quiet", None)
    return bool(q()) if q is not None else False


def exchange(c: Any, up: Iterable[tuple[int, int, tuple]], tick: int, asked: bool = True,
             mute: Muting | None = None) -> list | None:
    """The messages `up` ((node, kind, fields), in the order sent) to
    coordinator c but the muted ones (`mute`, read from c now when not
    given), then c.tick(tick): its commands [(node, kind, fields), ...].
    None, and no tick, when c heard nothing and was not `asked`."""
    if not (deliver(c, up, tick, mute) or asked):
        return None
    return c.tick(tick)


def deliver(c: Any, up: Iterable[tuple[int, int, tuple]], tick: int,
            mute: Muting | None = None) -> bool:
    """The first half of `exchange`, for a driver that ticks c on its own
    (the host process): the messages `up` to c.on_message in the order sent
    but the muted ones (`mute`, read from c now when not given); whether c
    heard any."""
    kind_m, drop = (mute if mute is not None else muting(c))[:2]
    heard = False
    for node, kind, fields in up:
        if kind == kind_m and node in drop:
            continue
        c.on_message(node, kind, fields, tick)
        heard = True
    return heard
