"""The simulated swarm on a CAN bus.

`Gateway` is the robots' side: ONE python-can bus multiplexing every simulated
robot (one bus per robot on a virtual channel would make each frame cost
O(robots)). Robot sends are batched and put on the bus at the tick boundary;
received host commands go to per-node inboxes (node 0 = every robot).

`CanLink` is an engine Link (sim_backend.engine.Link) whose host side is a
second bus on the same channel. It is deterministic: at the tick boundary the
host reads exactly as many frames as the gateway put on the bus this tick, and
the gateway reads exactly as many as the host sent, so a run over CAN equals
the in-process run frame for frame (`touchswarm run --link can`).

`Faults` sits between the robots and the bus and drops, duplicates and
reorders frames within a window, from its own seeded RNG.
"""

from __future__ import annotations

import heapq
import itertools
import os
import random
from collections import deque
from typing import Any

import can

from bridge.links.canbus import converted, shutdown_quietly
from bridge.links.codec import BadFrames, Decoder, Message, encode
from bridge.links.errors import LinkTimeoutError
from firmware_logic.messages import HELLO

RECV_TIMEOUT = 2.0   # seconds a frame known to be on a virtual bus may take

_serial = itertools.count(1)


def private_channel(prefix: str = "touchswarm") -> str:
    """A virtual channel name no other run in this process shares."""
    return f"{prefix}-{os.getpid()}-{next(_serial)}"


class Faults:
    """Frame loss, duplication, delay and reordering within a window, seeded.

    delay: each frame that is not lost is held back 0..delay ticks (drawn
    per frame, so delayed frames also overtake each other); `apply` is
    called once per tick, `now` the tick (None: count the calls)."""

    def __init__(self, seed: int = 0, loss: float = 0.0, dup: float = 0.0,
                 window: int = 1, delay: int = 0) -> None:
        if not (0 <= loss < 1 and 0 <= dup < 1 and window >= 1 and delay >= 0):
            raise ValueError("expected 0 <= loss < 1, 0 <= dup < 1, window >= 1, delay >= 0")
        self.rng = random.Random(seed)
        self.loss = loss
        self.dup = dup
        self.window = window
        self.delay = delay
        self.dropped = 0
        self.duplicated = 0
        self.delayed = 0
        self.held: list[tuple[int, int, Any]] = []   # heap of (due tick, order, frame)
        self.calls = 0
        self._order = 0

    def due(self, now: int) -> bool:
        """Is a held frame due at tick `now`? (`held` is a heap: the earliest first)"""
        return bool(self.held) and self.held[0][0] <= now

    def apply(self, frames: list[Any], now: int | None = None) -> list[Any]:
        if now is None:
            now = self.calls
        self.calls += 1
        out = []
        for f in frames:
            if self.rng.random() < self.loss:
                self.dropped += 1
                continue
            out.append(f)
            if self.rng.random() < self.dup:
                self.duplicated += 1
                out.append(f)
        if self.delay > 0:
            for f in out:
                d = self.rng.randrange(self.delay + 1)
                self.delayed += d > 0
                heapq.heappush(self.held, (now + d, self._order, f))
                self._order += 1
            out = []
            while self.due(now):
                out.append(heapq.heappop(self.held)[2])
        if self.window > 1:
            for i in range(0, len(out), self.window):
                chunk = out[i:i + self.window]
                self.rng.shuffle(chunk)
                out[i:i + self.window] = chunk
        return out


def faults_of(sc: Any, seed: int) -> tuple[Faults | None, Faults | None]:
    """The scenario's link faults (linkLoss, linkDup, linkReorder,
    linkDelay) as the injectors up (robots -> host) and down, seeded from
    the run seed; (None, None) when all are off, so such a link is the plain
    one."""
    if not (sc.linkLoss or sc.linkDup or sc.linkReorder > 1 or sc.linkDelay):
        return None, None
    return (Faults(seed * 2 + 1, sc.linkLoss, sc.linkDup, sc.linkReorder, sc.linkDelay),
            Faults(seed * 2 + 2, sc.linkLoss, sc.linkDup, sc.linkReorder, sc.linkDelay))


class Gateway:
    """Every simulated robot on one bus (the robots' side of a link)."""

    def __init__(self, bus: can.BusABC, nodes: list[int], faults: Faults | None = None,
                 bad: BadFrames | None = None, faults_down: Faults | None = None,
                 keys: dict[int, bytes] | None = None, fresh: Any = None) -> None:
        self.bus = bus
        self.nodes = list(nodes)
        self.faults = faults
        self.faults_down = faults_down     # applied to what the gateway receives
        self.decoder = Decoder("robot", bad or BadFrames("gateway"))
        # with keys, host commands are obeyed only when authenticated, and a
        # HELLO carries a MAC and the robot's freshness floor; `fresh`: a
        # secoc.FreshnessStore that keeps the robots' counters across restarts
        self.opener = None
        if keys is not None:
            from bridge.links.secoc import Opener   # cryptography only when keyed
            self.opener = Opener(keys, self.decoder.bad, fresh)
        self.up: list[can.Message] = []
        self.hellos: dict[int, can.Message] = {}     # each robot's HELLO, for a resync
        self.resynced: dict[int, int] = {}
        self.flushes = 0
        self.inbox: dict[int, deque] = {n: deque() for n in nodes}
        self.sent = 0
        self.received = 0

    def robot_send(self, node: int, kind: int, fields: tuple) -> None:
        frame = encode(node, kind, fields)
        if self.opener is not None:
            if kind == HELLO:
                self.hellos[node] = frame
                frame = self.opener.hello(frame)
            else:
                # a report is sealed too; before the robot took a host
                # command it is held back (secoc.Opener.seal_report)
                sealed = self.opener.seal_report(node, kind, fields)
                if sealed is None:
                    return
                frame = sealed
        self.up.append(frame)

    def robot_recv(self, node: int) -> tuple[int, tuple] | None:
        q = self.inbox[node]
        return q.popleft() if q else None

    def flush(self) -> int:
        """Put this tick's robot frames on the bus; return how many went."""
        self.flushes += 1
        if self.opener is not None and self.opener.stale:
            self._resync()
        frames, self.up = self.up, []
        if self.faults is not None:
            frames = self.faults.apply(frames)
        with converted("gateway send"):
            for f in frames:
                self.bus.send(f)
        self.sent += len(frames)
        return len(frames)

    def _resync(self) -> None:
        """A robot that got genuine but stale host commands says HELLO again
        (at most every RESYNC ticks): its HELLO names its freshness floor,
        and a host that lost its counters continues above it."""
        from bridge.links.secoc import RESYNC
        opener = self.opener
        assert opener is not None
        for node in sorted(opener.stale):
            plain = self.hellos.get(node)
            if plain is not None and self.flushes - self.resynced.get(node, -RESYNC) >= RESYNC:
                self.resynced[node] = self.flushes
                self.up.append(opener.hello(plain))
        opener.stale.clear()

    def deliver(self, frame: can.Message) -> None:
        if self.opener is not None:
            opened = self.opener.open(frame)
            if opened is None:
                return
            frame = opened
        m = self.decoder.decode(frame)
        if m is None:
            return
        node, kind, fields = m
        if node == 0:
            for q in self.inbox.values():
                q.append((kind, fields))
        elif node in self.inbox:
            q = self.inbox[node]
            q.append((kind, fields))
        self.received += 1

    def drain(self, count: int | None = None, timeout: float = RECV_TIMEOUT) -> int:
        """Read `count` frames (each within `timeout`), or, with None, every frame
        already waiting; deliver them to the inboxes. Returns frames read."""
        n = 0
        got = []
        with converted("gateway recv"):
            while count is None or n < count:
                try:
                    frame = self.bus.recv(timeout if count is not None else 0.0)
                except (ValueError, IndexError):   # an adapter line that does not parse
                    self.decoder.bad.add("malformed adapter line")
                    continue
                if frame is None:
                    if count is None:
                        break
                    raise LinkTimeoutError(f"gateway: {n} of {count} host frames arrived "
                                           f"within {timeout} s")
                n += 1
                got.append(frame)
        if self.faults_down is not None:
            got = self.faults_down.apply(got)
        for frame in got:
            self.deliver(frame)
        return n


class CanLink:
    """An engine Link over a python-can bus (default: a private virtual channel)."""

    def __init__(self, nodes: list[int], channel: str | None = None, *,
                 faults_up: Faults | None = None, faults_down: Faults | None = None) -> None:
        # the injectors are keyword-only: passed by position they once landed
        # in `channel`, and the link ran with the down injector as the up one
        if channel is not None and not isinstance(channel, str):
            raise TypeError(f"CanLink channel: expected a str, got {type(channel).__name__}")
        from bridge.links import open_bus
        self.channel = channel or private_channel()
        self._closed = False
        self.robot_bus = open_bus(f"virtual://{self.channel}")
        try:
            self.host_bus = open_bus(f"virtual://{self.channel}")
        except Exception:
            self.robot_bus.shutdown()
            raise
        self.gateway = Gateway(self.robot_bus, nodes, faults_up)
        self.faults_down = faults_down
        self.host_decoder = Decoder("host", BadFrames("host"))
        self.down: list[can.Message] = []
        self.frames_up = 0
        self.frames_down = 0
        self.tick = 0          # polls (one per engine tick): the link's clock for delayed frames

    # robots' side
    def robot_send(self, node: int, kind: int, fields: tuple) -> None:
        self.gateway.robot_send(node, kind, fields)

    def robot_recv(self, node: int) -> tuple[int, tuple] | None:
        if self.down or (self.faults_down is not None and self.faults_down.due(self.tick)):
            self._flush_down()
        return self.gateway.robot_recv(node)

    def _flush_down(self) -> None:
        frames, self.down = self.down, []
        if self.faults_down is not None:
            frames = self.faults_down.apply(frames, self.tick)
        with converted("host send"):
            for f in frames:
                self.host_bus.send(f)
        self.frames_down += len(frames)
        self.gateway.drain(len(frames))

    # host's side
    def poll(self, timeout: float) -> list[Message]:
        # the robots' frames of this tick are flushed onto the bus here, so
        # each is waited for (RECV_TIMEOUT), not `timeout`: an engine polls 0
        self.tick += 1
        n = self.gateway.flush()
        self.frames_up += n
        out: list[Message] = []
        with converted("host recv"):
            for i in range(n):
                frame = self.host_bus.recv(RECV_TIMEOUT)
                if frame is None:
                    raise LinkTimeoutError(f"host: {i} of {n} robot frames arrived "
                                           f"within {RECV_TIMEOUT} s")
                m = self.host_decoder.decode(frame)
                if m is not None:
                    out.append(m)
        return out

    def send(self, node: int, kind: int, fields: tuple) -> None:
        self.down.append(encode(node, kind, fields))

    def bad_frames(self) -> dict[str, int]:
        out = dict(self.host_decoder.bad.counts)
        for k, v in self.gateway.decoder.bad.counts.items():
            out[k] = out.get(k, 0) + v
        return out

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        if self.down:
            self.down = []
        shutdown_quietly(self.host_bus, "can link (host side)")
        shutdown_quietly(self.robot_bus, "can link (robots' side)")

    def __enter__(self) -> "CanLink":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
