"""The host controller process: any behaviour's coordinator + transport + journal.

It knows no behaviour's rules, only the host contract
(firmware_logic/roster.py). One host tick every `tick_seconds` of wall
time: frames that arrived since the last tick are handed to the coordinator
as they come (each report it accepts is journalled, through its `journal`
callback, before its ACK is queued), and at the tick the coordinator's
commands go out. Frames from nodes that never announced themselves with
HELLO (and are not in a resumed journal) are counted as bad frames and never
reach the coordinator.

Every decision the host acts on (the coordinator's `decision`: for the
thesis convergence, each transport step, delivery, each HALT) is journalled
with a snapshot of the state it leads to BEFORE its command is sent; `resume`
replays the journal's reports into a fresh coordinator and adopts each
snapshot at its place, so a host killed at any moment goes on where it
stopped: it never makes a decision twice (a transport step, the start of the
transport after delivery).

Liveness: `run` gives up when no known robot (one that said HELLO) has been
heard for `bus_timeout` seconds, or one of the coordinator's `carriers()` (the thesis: a robot whose
touch was accepted, the object cannot move without it) for `node_timeout`
seconds; the summary then says why. A command the link does not take within
its write timeout (LinkTimeoutError: an adapter that stopped reading) is
counted (`write_timeouts`) and the run goes on, so these limits and a signal
still end it.
"""

from __future__ import annotations

import inspect
import logging
import time
from types import SimpleNamespace
from typing import Any, Callable

from bridge.errors import UsageError
from bridge.links.codec import UNANNOUNCED, BadFrames, Message
from bridge.links.errors import LinkTimeoutError
from bridge.host.journal import REJECTED_KEPT, Journal, JournalError, Report
from firmware_logic import messages as msg
from firmware_logic import roster
from sim_backend import registry
from sim_backend.coordinator import HostCoordinator, lacks
from sim_backend.exchange import muting, wake
from sim_backend.link import HostEnd
from sim_backend.scenario import CHOICES

# A coordinator is any behaviour's that meets the host contract
# (firmware_logic/roster.py); this alias only documents what the host handles.
Coordinator = Any

log = logging.getLogger(__name__)

HALT_REPEATS = 10   # HALT is broadcast on this many ticks after the mission is done (not ACKed)
# the journal's live view (poses, bad frames; `touchswarm view`) is written at
# most once per this many host ticks: ten times a second at the 10 ms tick,
# more often than the page polls (five times a second)
LIVE_EVERY = 10

# The host contract (firmware_logic/roster.py, docs/writing-a-behaviour.md
# "What the host needs"): make_coordinator keywords for journalling each
# report before its ACK and logging refused ones, and what resume, the
# decisions and the liveness checks call (sim_backend.coordinator.HostCoordinator).
# A Coordinator deriving from firmware_logic.roster.Roster has all of it.
HOST_KEYWORDS = ("journal", "cells", "on_reject")


def host_behaviour(name: str | None, sc: Any = None) -> registry.Behaviour:
    """The behaviour `touchswarm host` runs, checked to meet the host
    contract; UsageError (one line) for an unknown one or one whose
    coordinator does not, before any port or journal is touched."""
    try:
        b = registry.load(name).activate()
    except registry.BehaviourError as err:
        raise UsageError(f"host: {err}") from None
    params = inspect.signature(b.package.make_coordinator).parameters
    missing = [k for k in HOST_KEYWORDS if k not in params]
    if not missing and sc is not None:
        coord = b.coordinator(sc, journal=None, cells=None, on_reject=None)
        missing = lacks(coord, HostCoordinator)
    if missing:
        raise UsageError(f"host: behaviour {b.name!r} cannot run in the host process: its "
                         f"coordinator lacks {', '.join(missing)} (the host contract: "
                         f"derive it from firmware_logic.roster.Roster); run it with "
                         f"`touchswarm run --behaviour {b.name} --link can`")
    return b


class NotOpen:
    """The host's end before its ports open: `touchswarm host` builds the
    host (and resumes its journal) first, so that a journal it cannot resume
    is refused before any robot is told anything, then sets host.transport."""

    def poll(self, timeout: float) -> list[Message]:
        raise RuntimeError("the host's transport is not open yet")

    def send(self, node: int, kind: int, fields: tuple) -> None:
        raise RuntimeError("the host's transport is not open yet")

    def bad_frames(self) -> dict[str, int]:
        return {}

    def close(self) -> None:
        pass


class HostProcess:
    def __init__(self, transport: HostEnd, weight: int, home_x: int = -15,
                 home_y: int = -15, journal: Journal | None = None,
                 tick_seconds: float = 0.01,
                 on_event: Callable[[str], None] | None = None,
                 world_size: int | None = None,
                 cells: list[tuple[int, int]] | None = None,
                 behaviour: str | None = None, arrival: str = CHOICES["arrival"][0],
                 scenario: Any = None) -> None:
        """world_size: the arena's half width in patches (None: what a byte
        carries); cells: the object's cells when the host knows them (a
        simulated swarm), else a touch need only be plausible. behaviour: a
        name or folder (default thesis) whose coordinator the host runs; it
        must pass host_behaviour(). arrival: the scenario's arrival rule
        (sim_backend/scenario.py CHOICES), which the host's coordinator applies.
        scenario: the whole scenario (its arrival wins), for a behaviour whose
        coordinator needs more than the arena and the weight (aggregation: the
        swarm's size and its own parameters)."""
        self.transport = transport
        self.journal = journal
        self.tick_seconds = tick_seconds
        self.on_event = on_event
        self.bad = BadFrames("host")
        self.rejects_logged: set[str] = set()
        # the host knows the arena and the object's weight, not a whole scenario
        # (the robots may be real): the coordinator's view of one
        sc = scenario if scenario is not None else SimpleNamespace(
            weight_centi=weight, homeX=home_x, homeY=home_y, worldSize=world_size,
            arrival=arrival)
        self.behaviour = host_behaviour(behaviour, sc)
        if journal is not None:
            journal.bind(str(behaviour or "thesis"))    # JournalError: another behaviour's
        from perception import host_coordinator
        self.coord = host_coordinator(self.behaviour, sc, journal=self._journal_report,
                                      cells=cells, on_reject=self._rejected)
        self.tick = 0
        self.halts_sent = 0
        self.resumed = 0
        self.messages = 0
        self.gave_up: str | None = None       # why run() stopped waiting for the robots
        self.gave_up_on: str | None = None    # which limit: "bus" or "node"
        self.stopped: str | None = None       # why run() was stopped from outside
        self.write_timeouts = 0               # ticks whose commands the link did not take
        self.poses: dict[int, list[int]] = {}     # node -> [tick, *its last HEARTBEAT fields]
        self.live_written: dict[str, Any] | None = None
        self.kind_now = 0                     # the kind of the report being handled
        self.uncommitted: list[str] = []      # events of reports not yet committed
        self.mute = muting(self.coord)        # what it declared muted at its last tick()

    # -- journal ----------------------------------------------------------------

    def snapshot(self) -> dict[str, Any]:
        """What a resumed host needs to go on from this moment."""
        return {"host": {"tick": self.tick, "halts_sent": self.halts_sent},
                "coordinator": self.coord.snapshot()}

    def resume(self, journal: Journal, after: Callable[[Any], None] | None = None) -> int:
        """Replay a journal into this (fresh) host: its reports in order
        through the coordinator's own checks, each decision's snapshot
        adopted at its place; return the reports the coordinator holds.
        `after(entry)` is called once each entry is in (the live view's plots)."""
        c = self.coord
        refused = sum(c.rejected.values())
        replayed = 0
        for e in journal.entries():
            if isinstance(e, Report):
                c.replay(e.node, e.kind, e.fields, e.tick)
                replayed += 1
            else:
                state = e.state.get("coordinator", {})
                for k, v in state.items():
                    have = getattr(c, k, None)
                    if have is not None and isinstance(have, tuple) != isinstance(v, list):
                        raise JournalError(
                            f"journal {journal.path}: the snapshot at tick {e.tick} sets "
                            f"{k} to {v!r}, not {'a list' if isinstance(have, tuple) else 'an integer'}"
                            f"; not a journal this host can resume")
                unknown = c.adopt(state)
                if unknown:
                    log.warning("journal snapshot: ignoring unknown coordinator "
                                "attributes %s", ", ".join(sorted(unknown)))
                self.halts_sent = int(e.state.get("host", {}).get("halts_sent", 0))
            if after is not None:
                after(e)
        self.tick = max(self.tick, journal.last_tick())
        self.mute = muting(c)                 # the adopted state's declaration
        self.resumed = len(c.touches)
        dropped = sum(c.rejected.values()) - refused
        self._event(f"resumed {self.resumed} touches from {len(c.nodes)} nodes "
                    f"({journal.path}, {replayed} reports); {self.phase()}"
                    + (f"; {dropped} journalled reports rejected" if dropped else ""))
        return self.resumed

    def phase(self) -> str:
        text = self.coord.status()
        if self.coord.done():
            text += f", HALT sent {self.halts_sent}/{HALT_REPEATS}"
        return text

    def _journal_report(self, node: int, kind: int, fields: tuple, tick: int) -> None:
        # called by the coordinator for a report that changed what it knows,
        # before the report's ACK is queued
        if self.journal is not None:
            # committed with the tick's other reports, before its commands
            # (their ACKs) are sent: step()
            self.journal.add_report(node, kind, fields, self.tick, commit=False)
        name, layout = msg.SCHEMA[kind]
        way = "to" if msg.spec(kind)[2] == msg.DOWN else "from"    # a RELEASE is the host's
        text = (f"tick {self.tick}: {name} {way} robot {node} journalled ("
                + ", ".join(f"{f[0]} {v}" for f, v in zip(layout, fields)) + ")")
        if self.journal is None:
            self._event(text)
        else:
            self.uncommitted.append(text)      # said once it is durable: _commit()

    def _commit(self) -> None:
        """Make the reports journalled since the last commit durable, then
        say so (an operator, or a test killing the host, may act on it)."""
        if self.journal is not None:
            self.journal.commit()
        if self.uncommitted:
            texts, self.uncommitted = self.uncommitted, []
            for text in texts:
                self._event(text)

    def _rejected(self, reason: str, node: int, fields: tuple, kind: int = 0) -> None:
        # like a bad frame: the first of each reason is logged, the rest counted
        # (`rejected` in the summary), so a flood cannot flood the log; the
        # first REJECTED_KEPT of each are journalled as evidence (never replayed).
        # kind: the report's, when the coordinator judged it later than it
        # was handed over (at its tick's end), else the one being handled
        kind = kind or self.kind_now
        if self.journal is not None and self.coord.rejected.get(reason, 0) <= REJECTED_KEPT \
                and kind:
            self.journal.add_rejected(node, kind, fields, self.tick, reason, commit=False)
        if reason not in self.rejects_logged:
            self.rejects_logged.add(reason)
            log.warning("tick %d: rejected a report from robot %d (%s): %s; further ones "
                        "for this reason are only counted", self.tick, node, reason, fields)

    def _event(self, text: str) -> None:
        log.info("%s", text)
        if self.on_event is not None:
            self.on_event(text)

    # -- input ----------------------------------------------------------------------

    def handle(self, messages: list[Message]) -> None:
        """Messages as they arrive, to the coordinator by the engines' rule
        (in order, the muted ones dropped: exchange.Muting.drops), one at
        a time: whether a node is announced changes with each HELLO handed
        over, and a rejected report is journalled with its kind."""
        c = self.coord
        nodes = c.nodes
        tick = self.tick
        mute = self.mute
        self.messages += len(messages)
        for node, kind, f in messages:
            if kind != msg.HELLO and node not in nodes:
                self.bad.add(UNANNOUNCED, "%s from node %d" % (msg.SCHEMA[kind][0], node))
                continue
            if kind == msg.HEARTBEAT:
                self.poses[node] = [tick, *f]
            if mute.drops(node, kind, f):
                continue
            self.kind_now = kind
            c.on_message(node, kind, f, tick)
        self.kind_now = 0

    # -- ticks --------------------------------------------------------------------------

    def step(self) -> None:
        """One host tick: decide, journal the decision, then send the commands.
        Not sim_backend/exchange.py's `exchange`, whose tick follows the
        messages at once: here they were handed over as they arrived
        (handle), the state before the tick is kept for the decision, and
        the decision is journalled (committed) before any command is sent."""
        self.tick += 1
        c = self.coord
        repeat = c.done() and self.halts_sent < HALT_REPEATS
        # a quiet or idle coordinator's tick changes nothing: no snapshot to
        # compare (most ticks; a snapshot costs more than the rest of the tick)
        quiet = wake(c) > self.tick and not repeat
        before = None if quiet else c.snapshot()
        out = c.tick(self.tick)
        self.mute = muting(c, self.mute)
        if repeat:
            out.append((msg.HOST, msg.HALT, (0,)))          # a repeat: HALT is not ACKed
        self.halts_sent += sum(1 for m in out if m[1] == msg.HALT)
        decided = None if before is None else c.decision(before, out)
        if decided is not None and self.journal is not None:
            # before anything is sent: a command on the bus is always journalled
            self.journal.add_decision(self.tick, decided[0], self.snapshot())
        self._commit()                   # the tick's reports and decision: one fsync
        try:
            for node, kind, fields in out:
                self.transport.send(node, kind, fields)
        except LinkTimeoutError as err:
            # the link took no frame within its write timeout (an adapter
            # that stopped reading): this tick's other commands are dropped
            # too (a robot retransmits for its ACK, the coordinator resends a
            # step, HALT repeats); the liveness limits and a signal still end
            # the run
            self.write_timeouts += 1
            if self.write_timeouts == 1:
                log.warning("tick %d: %s; the tick's commands are dropped, further "
                            "write timeouts are only counted", self.tick, err)
                self._event(f"tick {self.tick}: write timed out ({err})")
        if decided is not None and decided[1]:
            self._event(f"tick {self.tick}: {decided[1]}")
        if self.journal is not None and self.tick % LIVE_EVERY == 0:
            self._journal_live()

    def _journal_live(self) -> None:
        """The live view for `touchswarm view`, when it changed."""
        view = {"poses": {str(n): p for n, p in sorted(self.poses.items())},
                "bad_frames": self.bad_frames(), "messages": self.messages}
        if view != self.live_written:
            assert self.journal is not None
            self.journal.set_live({"tick": self.tick, **view})
            self.live_written = view

    def done(self) -> bool:
        return self.coord.done() and self.halts_sent >= HALT_REPEATS

    def run(self, stop: Callable[[], bool] | None = None, max_ticks: int | None = None,
            clock: Callable[[], float] = time.monotonic, node_timeout: float | None = None,
            bus_timeout: float | None = None) -> dict[str, Any]:
        """Run until the object is home (and HALT repeated), `stop()`, max_ticks,
        or silence: no message from any robot for `bus_timeout` seconds, or from
        one carrier for `node_timeout` seconds (None: wait for ever). Every wait
        is on `clock`."""
        started = clock()
        next_tick = started + self.tick_seconds
        start_tick = self.tick
        heard_bus = started
        heard: dict[int, float] = {}      # node -> when last heard (this run)
        while not self.done():
            if stop is not None and stop():
                self.stopped = "stopped by a signal"
                self._event(f"tick {self.tick}: stopped")
                break
            if max_ticks is not None and self.tick - start_tick >= max_ticks:
                self.stopped = f"gave up after {max_ticks} ticks"
                self._event(f"tick {self.tick}: {self.stopped}")
                break
            now = clock()
            while now < next_tick:
                got = self.transport.poll(next_tick - now)
                now = clock()
                if got:
                    self.handle(got)
                    # liveness: only frames from known nodes (announced with
                    # HELLO); noise or a forger's unknown ids keep nothing alive
                    known = self.coord.nodes
                    for m in got:
                        if m[0] in known:
                            heard_bus = now
                            heard[m[0]] = now
            self.step()
            why = self._silence(now, started, heard, heard_bus, node_timeout, bus_timeout)
            if why is not None:
                self.gave_up_on, self.gave_up = why
                self._event(f"tick {self.tick}: gave up: {self.gave_up}")
                break
            next_tick += self.tick_seconds
            if next_tick < now:
                next_tick = now + self.tick_seconds
        return self.finish()

    def finish(self) -> dict[str, Any]:
        """The summary, its outcome journalled (with the last live view)."""
        summary = self.summary()
        self._commit()
        if self.journal is not None:
            self._journal_live()         # the last poses, between two LIVE_EVERY ticks
            self.journal.set_outcome(summary["outcome"], summary["reason"], self.tick)
        return summary

    def _silence(self, now: float, started: float, heard: dict[int, float],
                 heard_bus: float, node_timeout: float | None,
                 bus_timeout: float | None) -> tuple[str, str] | None:
        """(limit, why) when the host should stop waiting for the robots."""
        if self.coord.done():
            return None              # only HALTs left to send; halted robots may fall silent
        if bus_timeout is not None and now - heard_bus >= bus_timeout:
            return "bus", f"no message from any robot for {now - heard_bus:.1f} s"
        if node_timeout is not None:
            # only carriers: a searching robot that died costs nothing, but the
            # object cannot move without every robot that holds it
            for node in self.coord.carriers():
                quiet = now - heard.get(node, started)
                if quiet >= node_timeout:
                    return "node", (f"robot {node} (a carrier: the object cannot move "
                                    f"without it) silent for {quiet:.1f} s")
        return None

    def bad_frames(self) -> dict[str, int]:
        out = dict(self.transport.bad_frames())
        for k, v in self.bad.counts.items():
            out[k] = out.get(k, 0) + v
        return out

    def outcome(self) -> tuple[str, str]:
        """(outcome, reason): how the mission ended by the host's own model
        (firmware_logic/roster.py OUTCOMES): delivered only with a delivered
        tick; else halted / stalled by the coordinator, stalled when the
        robots fell silent, stopped when run() was stopped or ran out of ticks."""
        c = self.coord
        ended = c.ended()
        if ended:
            return ended, c.status()
        if self.gave_up is not None:
            return roster.STALLED, self.gave_up
        return roster.STOPPED, (self.stopped or "not ended") + "; " + c.status()

    def summary(self) -> dict[str, Any]:
        c = self.coord
        outcome, reason = self.outcome()
        return {
            "ticks": self.tick,
            "nodes": sorted(c.nodes),
            "touches": [[t.node, t.seq] for t in c.touches],
            "power": c.power / 100,
            "leader": c.leader or None,
            "resumed": self.resumed,
            "duplicates": c.duplicates,
            "rejected": dict(c.rejected),
            "converged_tick": c.converged_tick if c.converged_tick >= 0 else None,
            "home_tick": c.delivered_tick if c.delivered_tick >= 0 else None,
            # true only for a delivered tick of the host's own model; a mission
            # the coordinator stopped (stalled, no path home) is not delivered
            "delivered": outcome == roster.DELIVERED,
            "outcome": outcome,
            "reason": reason,
            "transport_step": getattr(c, "step", 0),
            "gave_up": self.gave_up,
            "gave_up_on": self.gave_up_on,
            "messages": self.messages,
            "bad_frames": self.bad_frames(),
            "write_timeouts": self.write_timeouts,
        }
