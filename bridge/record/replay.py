"""Replay a recording: every robot's firmware on its recorded sensor stream
and receptions, the coordinator on the reports the host received; each
decision that differs from the recording is reported.

A robot's decisions are its actions (ACTION frames) and the messages it sent;
the coordinator's are the commands it sent. A robot whose firmware asks for a
different sensor reading than the recording holds has left the recorded path:
that divergence is reported and the robot is not replayed further.
"""

from __future__ import annotations

import json
import logging
import struct
import time
from collections import defaultdict, deque
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import can

from bridge.errors import UsageError
from bridge.links.codec import BadFrames, Decoder, Message
from bridge.record.formats import meta_path, record_format
from bridge.record.recorder import HOST, Q_RECV, Q_RECV_FIELD, Q_X, Q_Y, join_parts
from firmware_logic import messages as msg
from firmware_logic import hal
from sim_backend import registry
from sim_backend.exchange import exchange
from firmware_logic.hal import Hal
from sim_backend.scenario import check_seed
from sim_backend.world import World

log = logging.getLogger(__name__)

# what replay compares between the sidecar's summary and its own outcome
SUMMARY_KEYS = ("robots", "ticks", "touches", "home_tick")
QUERY_NAMES = dict(enumerate(hal.QUERY_NAMES))


class Diverged(Exception):
    pass


@dataclass
class Recording:
    meta: dict
    ticks: list[int] = field(default_factory=list)
    stamps: dict[int, float] = field(default_factory=dict)
    # node -> tick -> list
    sensors: dict[int, dict[int, list[tuple]]] = field(default_factory=lambda: defaultdict(dict))
    actions: dict[int, dict[int, list[tuple]]] = field(default_factory=lambda: defaultdict(dict))
    up: dict[int, list[Message]] = field(default_factory=lambda: defaultdict(list))
    down: dict[int, list[Message]] = field(default_factory=lambda: defaultdict(list))
    # tick -> the frames the host received, where they differ from `up` (a
    # faulty link); elsewhere the host received what the robots sent
    host_in: dict[int, list[Message]] = field(default_factory=dict)
    # robots' receptions recorded in full (recv_field frames): replay hands
    # them over as recorded; older recordings pass the host's commands on
    recv_fields: bool = False
    frames: int = 0
    bad: dict[str, int] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)


def _sidecar(path: Path) -> dict:
    """The sidecar's JSON, checked for the keys replay needs; UsageError naming
    the sidecar and what is wrong with it."""
    mp = meta_path(path)
    redo = f"record again with `touchswarm run --record {path.name}`"
    if not mp.is_file():
        raise UsageError(f"replay: {path} has no sidecar {mp.name} (scenario and seed); "
                         f"{redo}")
    from sim_backend.textfile import TextFileError, read_small_text
    try:
        meta = json.loads(read_small_text(mp))
    except TextFileError as err:
        raise UsageError(f"replay: sidecar {mp} cannot be read ({err}); {redo}") from None
    except json.JSONDecodeError as err:
        raise UsageError(f"replay: sidecar {mp} is not valid JSON ({err}); {redo}") from None
    if not isinstance(meta, dict):
        raise UsageError(f"replay: sidecar {mp} holds a JSON {type(meta).__name__}; expected "
                         f"an object with scenario and seed; {redo}")
    missing = [k for k in ("scenario", "seed") if k not in meta]
    if missing:
        raise UsageError(f"replay: sidecar {mp} is incomplete: no {' and no '.join(missing)}; "
                         f"{redo}")
    if not isinstance(meta["scenario"], dict):
        raise UsageError(f"replay: sidecar {mp}: scenario must be a JSON object of scenario "
                         f"keys, got {meta['scenario']!r:.40}")
    check_seed(meta["seed"], f"replay: sidecar {mp}: seed")
    frames = meta.get("frames")
    if frames is not None and (isinstance(frames, bool) or not isinstance(frames, int)
                               or frames < 0):
        raise UsageError(f"replay: sidecar {mp}: frames must be a count >= 0, got {frames!r}")
    summary = meta.get("summary")
    if summary is not None and not (isinstance(summary, dict)
                                    and all(k in summary for k in SUMMARY_KEYS)):
        raise UsageError(f"replay: sidecar {mp}: summary must be the run's summary object "
                         f"with {', '.join(SUMMARY_KEYS)}; {redo}")
    return meta


@contextmanager
def _quiet_python_can():
    """python-can logs a warning per line it cannot parse; replay's own checks
    say what is wrong in one line, so hold them back unless asked (-v)."""
    lg = logging.getLogger("can")
    old = lg.level
    if not lg.isEnabledFor(logging.INFO):
        lg.setLevel(logging.ERROR)
    try:
        yield
    finally:
        lg.setLevel(old)


def behaviour(meta: dict, path: Path, folder: Path | None = None) -> registry.Behaviour:
    """The behaviour the recorded run ran, put in use: `folder` when given
    (`replay --behaviour DIR`), else the sidecar's: an installed one by name,
    a folder by its path relative to the recording's folder (an absolute
    path, as older recordings wrote, as it is). Recordings made before
    behaviours existed ran the thesis."""
    ref = str(meta["scenario"].get("behaviour", "thesis"))
    name = meta.get("behaviour_name")
    where = f"replay: sidecar {meta_path(path)}"
    if folder is not None:
        try:
            b = registry.load(str(folder))
        except registry.BehaviourError as err:
            raise UsageError(f"replay: --behaviour: {err}") from None
        if name is not None and b.name != name:
            raise UsageError(f"replay: --behaviour {folder} is behaviour {b.name!r}; "
                             f"{path.name} was recorded with {name!r}")
        return b.activate()
    if ref not in registry.names():
        ref = str(registry.beside(ref, Path(path).resolve().parent))
        if not Path(ref).is_dir():
            raise UsageError(f"{where}: behaviour {meta['scenario'].get('behaviour')!r}"
                             f"{' (' + repr(name) + ')' if name else ''} is not a folder "
                             f"relative to {Path(path).parent or '.'} nor installed; point at its "
                             f"folder with `touchswarm replay --behaviour DIR {path}`")
        # the sidecar names, never imports: a folder only when the user
        # trusted it (--trust-behaviour DIR), or --behaviour DIR above
        try:
            registry.named_by_data(ref, where)
        except registry.BehaviourError as err:
            raise UsageError(str(err)) from None
    try:
        return registry.load(ref).activate()
    except registry.BehaviourError as err:
        raise UsageError(f"{where}: {err}") from None


def load(path: Path, folder: Path | None = None) -> Recording:
    """Read a recording and its sidecar. UsageError (bad input: the CLI exits 2)
    for a missing, unreadable, corrupt, truncated or mismatched recording."""
    path = Path(path)
    fmt = _recording_format(path)
    rec = Recording(meta=_sidecar(path))
    b = behaviour(rec.meta, path, folder)   # its own message kinds, before any frame is read
    rec.meta["scenario"]["behaviour"] = b.ref     # its name when installed, else its folder
    dec = Decoder("host", BadFrames("replay"), behaviour=b)
    _read_frames(path, fmt, _Sorter(rec, dec))
    rec.bad = dict(dec.bad.counts)
    _check_complete(rec, path)
    return rec


def _recording_format(path: Path) -> str:
    """The format of the recording file at `path` (by its suffix); UsageError
    when there is no such file, a directory or an empty one."""
    if not path.exists():
        raise UsageError(f"replay: no such recording {path}")
    if path.is_dir():
        raise UsageError(f"replay: {path} is a directory; expected a recording file made "
                         "by `touchswarm run --record`")
    fmt = record_format(path, "replay")
    if path.stat().st_size == 0:
        raise UsageError(f"replay: {path} is empty (0 bytes); expected a recording made by "
                         "`touchswarm run --record`")
    return fmt


class _Sorter:
    """Files each frame of a recording in its Recording: capture frames
    (SENSOR, ACTION) by robot and tick, the frames the host received on a
    faulty link, the host's commands and the robots' messages by tick."""

    def __init__(self, rec: Recording, dec: Decoder) -> None:
        self.rec = rec
        self.dec = dec
        self.tick = 0
        self.host_left = 0      # frames still to come of those the host received

    def frame(self, frame: can.Message) -> None:
        if frame.is_error_frame:
            return
        self.rec.frames += 1
        m = self.dec.decode_capture(frame)
        if m is None:
            return
        node, kind, f = m
        if kind in (msg.SENSOR, msg.ACTION):
            self.capture(node, kind, f, frame.timestamp)
        else:
            self.message(node, kind, tuple(f))

    def capture(self, node: int, kind: int, f: tuple, stamp: float) -> None:
        """A robot's sensor reading or action, or the host's count of the
        frames it received this tick (those frames follow)."""
        rec = self.rec
        t = self.tick + ((f[0] - self.tick) & 0xFFFF)   # 16-bit tick field, unwrapped
        if t != self.tick:
            self.tick = t
            rec.ticks.append(t)
            rec.stamps[t] = stamp
        if node == HOST and kind == msg.SENSOR and f[2] == Q_RECV:
            rec.host_in[t] = []
            self.host_left = f[3]
            return
        rec.recv_fields |= kind == msg.SENSOR and f[2] == Q_RECV_FIELD
        table = rec.sensors if kind == msg.SENSOR else rec.actions
        table[node].setdefault(t, []).append(tuple(f[2:]))

    def message(self, node: int, kind: int, f: tuple) -> None:
        """A frame on the bus: one the host received (after its count), a
        host command, or a robot's message."""
        rec = self.rec
        host_kind = kind in self.dec.schema.host_kinds
        if self.host_left > 0 and not host_kind:
            rec.host_in[self.tick].append((node, kind, f))
            self.host_left -= 1
        elif host_kind:
            rec.down[self.tick].append((node, kind, f))
        else:
            rec.up[self.tick].append((node, kind, f))


def _read_frames(path: Path, fmt: str, sorter: _Sorter) -> None:
    """Every frame of the recording through `sorter`; UsageError for a cut or
    damaged file, naming what its reader hit."""
    rec = sorter.rec
    try:
        with _quiet_python_can():
            for frame in can.LogReader(str(path)):
                sorter.frame(frame)
    except struct.error as err:
        # the .blf reader unpacks fixed-size headers: a short read is a cut file
        raise UsageError(f"replay: {path} is truncated or damaged: a {fmt} header ends "
                         f"early ({err}, after {rec.frames} frames)") from None
    except EOFError:
        raise UsageError(f"replay: {path} is truncated: its compressed stream ends early "
                         f"(after {rec.frames} frames)") from None
    except Exception as err:  # noqa: BLE001
        # python-can's readers fail on a damaged file with whatever their parser
        # hits (struct.error, UnicodeDecodeError, BLFParseError, zlib.error, ...)
        why = (str(err).splitlines() or [""])[0][:120]
        raise UsageError(f"replay: {path} is not a readable {fmt} recording "
                         f"({type(err).__name__}: {why})") from None


def _check_complete(rec: Recording, path: Path) -> None:
    """The recording against its sidecar: as many frames as it records, a
    sensor stream to replay; warnings where the sidecar cannot tell."""
    want = rec.meta.get("frames")
    if want is None:
        rec.warnings.append(f"sidecar {meta_path(path).name} has no frame count, so a "
                            "truncated recording cannot be told apart; replaying anyway")
    elif rec.frames < want:
        raise UsageError(f"replay: {path} is truncated: it holds {rec.frames} of the {want} "
                         f"frames its sidecar {meta_path(path).name} records")
    elif rec.frames > want:
        raise UsageError(f"replay: {path} holds {rec.frames} frames but its sidecar "
                         f"{meta_path(path).name} records {want}: the two belong to "
                         "different recordings")
    if not rec.ticks:
        raise UsageError(f"replay: {path} holds no SENSOR/ACTION capture frames, so there is "
                         f"no sensor stream to replay; record with `touchswarm run --record`")
    if "summary" not in rec.meta:
        rec.warnings.append(f"sidecar {meta_path(path).name} has no run summary (the run "
                            "was interrupted?), so the outcome is not checked")


class ReplayHal(Hal):
    """Answers the firmware from one robot's recorded sensor stream."""

    def __init__(self, node: int, inbox: deque, full: bool = False) -> None:
        self.node = node
        self.inbox = inbox
        self.full = full        # the recording holds each reception in full
        self.tape: deque = deque()
        self.acts: list[tuple] = []
        self.sent: list[Message] = []

    def _next(self, query: int, arg: int) -> int:
        want = "%s(%d)" % (QUERY_NAMES[query], arg)
        if not self.tape:
            raise Diverged(f"firmware asked {want}, the recording has no more readings")
        q, a, v = self.tape.popleft()
        if q != query or (query != Q_RECV and a != arg):
            raise Diverged(f"firmware asked {want}, the recording has "
                           f"{QUERY_NAMES.get(q, q)}({a})")
        return v if query != Q_RECV else a

    def x(self) -> int:
        return self._next(Q_X, 0)

    def y(self) -> int:
        return self._next(Q_Y, 0)

    def probe(self, heading: int) -> int:
        return self._next(1, heading)

    def field_ahead(self, heading: int) -> int:
        return self._next(2, heading)

    def field_here(self) -> int:
        return self._next(3, 0)

    def uphill(self) -> int:
        return self._next(4, 0)

    def holding(self) -> int:
        return self._next(5, 0)

    def forward(self, heading: int, step: int) -> None:
        self.acts.append((1, heading, step))

    def claim(self, heading: int) -> None:
        self.acts.append((2, heading, 0))

    def carry(self, dx: int, dy: int) -> None:
        self.acts.append((3, dx, dy))

    def beacon(self, on: int) -> None:
        self.acts.append((4, on, 0))

    def send(self, kind: int, a0: int, a1: int, a2: int, a3: int, a4: int, a5: int) -> None:
        n = len(msg.fields(kind))
        self.sent.append((self.node, kind, (a0, a1, a2, a3, a4, a5)[:n]))

    def recv(self, buf: list) -> int:
        kind = self._next(Q_RECV, 0)
        if kind == 0:
            return 0
        if kind not in msg.SCHEMA:
            raise Diverged(f"the recording says message kind {kind} was received, "
                           f"which the behaviour does not know")
        parts = []
        while self.tape and self.tape[0][0] == Q_RECV_FIELD:
            parts.append(self.tape.popleft()[1:])
        if parts or self.full:
            # what the robot was handed, faults and all
            try:
                fields = join_parts(kind, parts)
            except ValueError as err:
                raise Diverged(f"the recorded {msg.SCHEMA[kind][0]} received: {err}") from None
            for j, v in enumerate(fields):
                buf[j] = v
            return kind
        if not self.inbox:
            raise Diverged(f"the recording says {msg.SCHEMA[kind][0]} was received, "
                           f"but the host sent nothing more to robot {self.node}")
        k, fields = self.inbox.popleft()
        if k != kind:
            raise Diverged(f"received {msg.SCHEMA[kind][0]} in the recording, "
                           f"but the host's next frame for it is {msg.SCHEMA[k][0]}")
        for j, v in enumerate(fields):
            buf[j] = v
        return kind


def _fmt(m: Message) -> str:
    node, kind, f = m
    return "%s_%d%s" % (msg.SCHEMA[kind][0], node, tuple(f))


class _Replayer:
    """One recording replayed tick by tick: the firmware of every robot fed
    its recorded readings, the host fed the recorded reports; whatever they
    do that the recording does not hold is a divergence."""

    def __init__(self, rec: Recording, beh: registry.Behaviour, sc: Any, seed: int) -> None:
        self.rec = rec
        self.nodes = sorted(set(rec.sensors) | set(rec.actions))
        self.robots = {n: beh.make_robot(n, seed, sc) for n in self.nodes}
        self.inbox: dict[int, deque] = {n: deque() for n in self.nodes}
        self.hals = {n: ReplayHal(n, self.inbox[n], rec.recv_fields) for n in self.nodes}
        self.stopped: set[int] = set()
        # the recorded run was a simulation: the host may check touches against
        # the object's true cells
        from perception import host_coordinator
        self.coord = host_coordinator(beh, sc, cells=World(sc, seed).object_cells)
        self.divergences: list[str] = []
        self.counts = {"sensor_readings": 0, "actions": 0, "robot_messages": 0,
                       "host_commands": 0}

    def diverge(self, text: str) -> None:
        self.divergences.append(text)

    def tick(self, t: int) -> None:
        sent_up: dict[int, list[Message]] = defaultdict(list)
        for m in self.rec.up.get(t, []):
            sent_up[m[0]].append(m)
        for n in self.nodes:
            if n not in self.stopped:
                self.robot(n, t, sent_up.get(n, []))
        recorded_down = self.rec.down.get(t, [])
        self.host(t, recorded_down)
        # what the host sent reaches the robots' inboxes for the next tick
        # (a recording without the robots' receptions in full)
        for node, kind, f in ([] if self.rec.recv_fields else recorded_down):
            for n in (self.nodes if node == 0 else [node]):
                if n in self.inbox:
                    self.inbox[n].append((kind, f))

    def robot(self, n: int, t: int, want_sent: list[Message]) -> None:
        """Robot n's step at tick t on its recorded readings: its actions and
        messages against the recorded ones."""
        hal = self.hals[n]
        tape = self.rec.sensors[n].get(t, [])
        self.counts["sensor_readings"] += len(tape)
        hal.tape = deque(tape)
        hal.acts = []
        hal.sent = []
        try:
            self.robots[n].step(hal)
            if hal.tape:
                raise Diverged(f"firmware left {len(hal.tape)} recorded readings unused")
        except Diverged as err:
            self.diverge(f"tick {t} robot {n}: {err}; robot not replayed further")
            self.stopped.add(n)
            return
        want_acts = self.rec.actions[n].get(t, [])
        self.counts["actions"] += len(want_acts)
        if hal.acts != want_acts:
            self.diverge(f"tick {t} robot {n}: actions {hal.acts}, recorded {want_acts}")
        self.counts["robot_messages"] += len(want_sent)
        if hal.sent != want_sent:
            self.diverge(f"tick {t} robot {n}: sent {[_fmt(m) for m in hal.sent]}, "
                         f"recorded {[_fmt(m) for m in want_sent]}")

    def host(self, t: int, recorded_down: list[Message]) -> None:
        """The host at tick t: the recorded reports in, its commands compared."""
        self.counts["host_commands"] += len(recorded_down)
        rec = self.rec
        host_in = rec.host_in[t] if t in rec.host_in else rec.up.get(t, [])
        # the engine's own tick boundary, as the recorded run had it
        down = exchange(self.coord, host_in, t)
        assert down is not None          # asked every tick
        out = [(node, kind, tuple(f)) for node, kind, f in down]
        if out != recorded_down:
            self.diverge(f"tick {t} host: sent {[_fmt(m) for m in out]}, "
                         f"recorded {[_fmt(m) for m in recorded_down]}")

    def check_summary(self) -> None:
        """The replayed outcome against the sidecar's run summary: the frames
        are all there, so a different outcome means the sidecar describes
        another run, or the firmware decides differently now."""
        recorded = self.rec.meta.get("summary")
        if recorded is None:
            return
        coord = self.coord
        replayed = {"robots": len(self.nodes), "ticks": len(self.rec.ticks),
                    "touches": len(coord.touches),
                    "home_tick": coord.delivered_tick if coord.delivered_tick >= 0 else None}
        for key, got in replayed.items():
            want = recorded[key]
            if key == "touches":
                want = len(want) if isinstance(want, list) else want
            if got != want:
                self.diverge(f"summary: {key} {got} replayed, {want} in the sidecar's run "
                             "summary")


def replay(path: Path, realtime: bool = False, limit: int = 50,
           folder: Path | None = None) -> dict:
    """Replay a recording; return a summary with a list of divergences.
    `folder`: the behaviour's folder when the sidecar's path does not reach it."""
    from sim_backend.scenario import validate

    rec = load(path, folder)
    sc = validate(dict(rec.meta["scenario"]), source=str(meta_path(Path(path))))
    seed = int(rec.meta["seed"])
    r = _Replayer(rec, behaviour(rec.meta, Path(path), folder), sc, seed)
    start = time.monotonic()
    t0 = rec.stamps[rec.ticks[0]] if rec.ticks else 0.0
    for t in rec.ticks:
        if realtime:
            delay = (rec.stamps[t] - t0) - (time.monotonic() - start)
            if delay > 0:
                time.sleep(delay)
        r.tick(t)
    r.check_summary()
    coord, divergences, counts, nodes = r.coord, r.divergences, r.counts, r.nodes
    return {
        "recording": str(path),
        "scenario": sc.name,
        "seed": seed,
        "robots": len(nodes),
        "ticks": len(rec.ticks),
        "frames": rec.frames,
        **counts,
        "touches": len(coord.touches),
        "delivered_tick": coord.delivered_tick if coord.delivered_tick >= 0 else None,
        "divergences": len(divergences),
        "differences": divergences[:limit],
        "bad_frames": rec.bad,
        "warnings": rec.warnings,
    }
