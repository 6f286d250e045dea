"""The host's side of a tick boundary, one rule for both engines
(sim_backend/engine.py `Engine.exchange`, sim_backend/batch/soa.py
`SoaEngine._exchange`), the host process (bridge/host/process.py) and
replay: the messages robots sent this tick go to the coordinator's
`on_message` in the order they were sent, except those it declared
`muted()` at its last `tick()` (they would change nothing:
tests/test_muted_messages.py); then it is asked to `tick()`, whose commands
go down to the robots. The batch engine asks only a coordinator that heard a
message or whose `wake` tick has come (`wake`: never while it is `quiet()`,
else its `idle_until()`); the reference asks every tick. The declarations
are sim_backend/coordinator.py's `Muted` and `Idling`.
"""

from __future__ import annotations

import struct
from typing import Any, Iterable, Sequence

from sim_backend.coordinator import Idling, Muted, has

NEVER = 1 << 62       # a `wake` tick no run reaches


class Muting:
    """What a coordinator's muted() dropped when it was read: messages of
    `kind` from the nodes in `drop`, and from node `node` those whose
    fields are `same` until it sends others (None: none); `key` tells a
    changed node set."""

    __slots__ = ("kind", "drop", "key", "node", "same")

    def __init__(self, kind: int, drop: frozenset, key: Any, node: int = 0,
                 same: tuple | None = None) -> None:
        self.kind, self.drop, self.key, self.node, self.same = kind, drop, key, node, same

    def drops(self, node: int, kind: int, fields: Sequence[int]) -> bool:
        """The rule: this message would change nothing, so it is not handed
        over. A message from `node` with other fields than `same` is handed
        over and ends the repeat clause until the declaration is read again
        (the coordinator's state may have moved past `same`)."""
        if kind != self.kind:
            return False
        if node in self.drop:
            return True
        if node == self.node and self.same is not None:
            if tuple(fields) == self.same:
                return True
            self.same = None
        return False


HEARS_ALL = Muting(-1, frozenset(), None)


def muting(c: Any, prev: Muting | None = None) -> Muting:
    """c.muted(): (kind, nodes, but[, same]), the messages of that kind from
    the nodes in `nodes` (a collection that only grows) other than `but`,
    and `but`'s with fields `same`, change nothing until c's next tick(); a
    coordinator without `muted` (or returning None) hears every message.
    `prev` is kept while the declaration is the same (the same kind,
    collection, size, `but` and `same`, the last not ended since); its node
    set while only `same` differs."""
    m = c.muted() if has(c, Muted) else None
    if m is None:
        return HEARS_ALL
    kind, nodes, but = m[0], m[1], m[2]
    same = tuple(m[3]) if len(m) > 3 and m[3] is not None else None
    key = (kind, id(nodes), len(nodes), but)
    if prev is not None and prev.key == key:
        if same == prev.same:
            return prev
        return Muting(kind, prev.drop, key, but, same)
    return Muting(kind, frozenset(nodes) - {but}, key, but, same)


class BatchMutes:
    """The muted() declarations of a batch's coordinators (one per run, robots
    lo[r] .. lo[r] + agents[r] - 1 of the batch nodes 1..agents[r]) held as
    arrays, so a batch engine drops the messages they mute in bulk, before
    decoding any, by the rule `Muting.drops` follows one by one: body.py's
    `sift` over these arrays (compiled by the batch engine; `keep` runs it
    as Python); `update(r, c)` after each tick() of run r's coordinator c."""

    def __init__(self, coords: Sequence[Any], lo: Sequence[int], agents: Sequence[int],
                 run_of: Any) -> None:
        import numpy as np
        # here, not at import: the host process (bridge/host) loads no kernel
        from sim_backend.batch.body import FIELDS
        self.lo, self.agents, self.run_of = lo, agents, run_of
        self.mutes = [HEARS_ALL] * len(coords)
        # per sender robot, the kind its run's declaration drops from it,
        # and the kind of its repeat clause (-1: none, no message's kind),
        # set exactly while that run's Muting has one (`same`)
        self.muted = np.full(len(run_of), -1, dtype=np.int64)
        self.repeats = np.full(len(run_of), -1, dtype=np.int64)
        # per run, its repeat clause's fields and how many (-1: no message's)
        self.same = np.zeros((len(coords), FIELDS), dtype=np.int64)
        self.same_n = np.full(len(coords), -1, dtype=np.int64)
        self._bytes, self._ns = self.same.data.cast("B"), self.same_n.data
        self._row = self.same.strides[0]
        self._runs = [int(x) for x in run_of]   # `end`'s, without a numpy scalar each
        # a clause's fields as a row of int64, by their count
        self._pack = tuple(struct.Struct(f"={k}q") for k in range(FIELDS + 1))
        for r, c in enumerate(coords):
            self.update(r, c)

    def update(self, r: int, c: Any) -> None:
        prev = self.mutes[r]
        m = muting(c, prev)
        if m is prev:
            return
        self.mutes[r] = m
        lo, n = self.lo[r], self.agents[r]
        if m.same is not None:
            self._same(r, m.same)
        # a new repeat clause of the same sender and kind (each transport
        # step's): its mark stands
        if not (prev.same is not None and m.same is not None and prev.node == m.node
                and prev.kind == m.kind):
            if prev.same is not None and 1 <= prev.node <= n:
                self.repeats[lo + prev.node - 1] = -1
            if m.same is not None and 1 <= m.node <= n:
                self.repeats[lo + m.node - 1] = m.kind
        if m.drop is prev.drop and m.kind == prev.kind:
            return
        self.muted[lo:lo + n] = -1
        for node in m.drop:
            if 1 <= node <= n:
                self.muted[lo + node - 1] = m.kind

    def _same(self, r: int, same: tuple) -> None:
        """Run r's repeat fields into its row, packed in one call (struct
        refuses what no message carries: a float numpy would truncate, a
        value past int64, more fields than a message holds); refused, the
        row is one no message's fields equal."""
        try:
            self._pack[len(same)].pack_into(self._bytes, r * self._row, *same)
        except (struct.error, IndexError):
            self._ns[r] = -1
            return
        self._ns[r] = len(same)

    def end(self, ended: Any) -> None:
        """The repeat clauses `sift` ended (ended[0] senders, ended[1:]),
        ended in their runs' declarations too (as Muting.drops ends one)."""
        mutes, runs = self.mutes, self._runs
        for i in ended[1:1 + int(ended[0])].tolist():
            mutes[runs[i]].same = None

    def keep(self, robot: Any, kind: Any, fields: Any) -> Any:
        """Which messages (sender robot, kind, fields: arrays, one row of
        fields each, in the order sent) reach their coordinators."""
        import numpy as np
        from sim_backend.batch.body import sift
        n, width = len(robot), fields.shape[1]
        kept = np.zeros((n, 3 + width), dtype=np.int64)
        ended = np.zeros(len(self.run_of) + 1, dtype=np.int64)
        # a clause longer than a message's fields: no message repeats it
        same_n = np.where(self.same_n > width, -1, self.same_n)
        k = sift(robot, kind, fields, width, self.muted, self.repeats, self.same, same_n,
                 self.run_of, kept, ended, n)
        self.end(ended)
        out = np.zeros(n, dtype=bool)
        out[kept[:k, 0]] = True
        return out


def quiet(c: Any) -> bool:
    """c.quiet(): tick() without a new message would change nothing (a
    coordinator without `quiet` is never quiet)."""
    q = getattr(c, "quiet", None)
    return bool(q()) if q is not None else False


def wake(c: Any) -> int:
    """The first tick at which c must be asked to tick() though it heard
    nothing: NEVER while it is quiet(), else its idle_until() (0: every
    tick; a coordinator without `idle_until` is asked every tick)."""
    q = getattr(c, "quiet", None)        # quiet(c), its call saved (a batch asks per event)
    if q is not None and q():
        return NEVER
    return int(c.idle_until()) if has(c, Idling) else 0


def exchange(c: Any, up: Iterable[tuple[int, int, tuple]], tick: int, asked: bool = True,
             mute: Muting | None = None) -> list | None:
    """The messages `up` ((node, kind, fields), in the order sent) to
    coordinator c but the muted ones (`mute`, read from c now when not
    given), then c.tick(tick): its commands [(node, kind, fields), ...].
    None, and no tick, when c heard nothing and was not `asked`."""
    mute = mute if mute is not None else muting(c)
    heard = False
    if mute is HEARS_ALL:                # nothing to drop: no test per message
        on_message = c.on_message
        for node, kind, fields in up:
            on_message(node, kind, fields, tick)
            heard = True
    else:
        for node, kind, fields in up:
            if mute.drops(node, kind, fields):
                continue
            c.on_message(node, kind, fields, tick)
            heard = True
    if not (heard or asked):
        return None
    return c.tick(tick)
