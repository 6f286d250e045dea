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

from typing import Any, Iterable, NamedTuple, Sequence


class Muting(NamedTuple):
    """What a coordinator's muted() dropped when it was read: messages of
    `kind` from the nodes in `drop`; `key` tells a changed declaration."""
    kind: int
    drop: frozenset
    key: Any

    def drops(self, node: int, kind: int) -> bool:
        """The rule: this message would change nothing, so it is not handed over."""
        return kind == self.kind and node in self.drop


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


class BatchMutes:
    """The muted() declarations of a batch's coordinators (one per run, robots
    lo[r] .. lo[r] + agents[r] - 1 of the batch nodes 1..agents[r]) held as
    arrays, so a batch engine drops the messages they mute in bulk, before
    decoding any (`keep`), by the rule `exchange` follows one by one;
    `update(r, c)` after each tick() of run r's coordinator c."""

    def __init__(self, coords: Sequence[Any], lo: Sequence[int], agents: Sequence[int],
                 run_of: Any) -> None:
        import numpy as np
        self.lo, self.agents, self.run_of = lo, agents, run_of
        self.mutes = [HEARS_ALL] * len(coords)
        self.kind = np.full(len(coords), HEARS_ALL.kind, dtype=np.int64)
        self.robot = np.zeros(len(run_of), dtype=bool)     # muted sender
        for r, c in enumerate(coords):
            self.update(r, c)

    def update(self, r: int, c: Any) -> None:
        prev = self.mutes[r]
        m = muting(c, prev)
        if m is prev:
            return
        self.mutes[r] = m
        lo, n = self.lo[r], self.agents[r]
        self.kind[r] = m.kind
        self.robot[lo:lo + n] = False
        for node in m.drop:
            if 1 <= node <= n:
                self.robot[lo + node - 1] = True

    def keep(self, robot: Any, kind: Any) -> Any:
        """Which messages (sender robot, kind: arrays) reach their coordinators."""
        return ~(self.robot[robot] & (kind == self.kind[self.run_of[robot]]))


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
    mute = mute if mute is not None else muting(c)
    heard = False
    for node, kind, fields in up:
        if mute.drops(node, kind):
            continue
        c.on_message(node, kind, fields, tick)
        heard = True
    if not (heard or asked):
        return None
    return c.tick(tick)
