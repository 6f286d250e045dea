"""Recording a run: every message on the link plus each robot's sensor readings
(SENSOR) and decisions (ACTION), as CAN frames in a python-can log file.

A recording is what happened, faults included (docs/protocol.md "Recordings
and replay"): the firmware's decisions (actions and messages) as it took them,
before any fault filter (a dead robot's actions and messages, a deadlocked
robot's moves, frames the link then loses), and what each side was handed
after the link's faults (loss, delay, duplication, reordering) and the body's
(a dead or defiant robot dropping commands): each robot's receptions in full,
and the frames the host received when they differ from those the robots sent.

File layout, per tick: for each robot in node order its SENSOR frames then its
ACTION frames; then the messages the robots sent (in the order they sent
them); then, only when the host received something else (a faulty link), a
SENSOR frame from node 0 (the host) with query recv and arg = the count of
frames it received, followed by those frames; then the host's commands as it
sent them. Frame timestamps are EPOCH + tick * TICK_SECONDS (+ 1 us per frame
within a tick), so the files are reproducible and `--realtime` replay paces by
them. A sidecar FILE.json keeps what the frames cannot: the scenario (with its
behaviour, also written as the top-level "behaviour") and the seed,
plus the number of frames written and the run's summary, so that replay can
tell a truncated or mismatched recording from a diverging one.

Sensor query codes (SENSOR.query; the codes are firmware_logic/hal.py's): 1 probe(arg=heading), 2 field_ahead(heading),
3 field_here, 4 uphill, 5 holding, 6 recv (arg = kind received, 0 none), 7 x,
8 y, 9 recv_field: after a recv reading, one frame per 16-bit part of each
field of the frame received (arg = field index + 16 * part, value = the part
as a signed 16-bit number).
Action codes (ACTION.action): 1 forward(a=heading, b=step), 2 claim(heading),
3 carry(dx, dy), 4 beacon(on).
"""

from __future__ import annotations

import json
import logging
from pathlib import Path
from typing import Any

import can

from bridge.links.codec import Message, encode
from firmware_logic import hal
from bridge.errors import UsageError
from bridge.record.formats import FORMATS, SUFFIXES, meta_path, record_format  # noqa: F401
from firmware_logic import messages as msg

log = logging.getLogger(__name__)

EPOCH = 1_700_000_000.0
# sidecar format; "frames" is written on every close, "summary" when the run
# finished (an interrupted run leaves a sidecar without it)
FORMAT = 1
TICK_SECONDS = 0.01
Q_RECV, Q_X, Q_Y, Q_RECV_FIELD = hal.RECV, hal.POS_X, hal.POS_Y, hal.RECV_FIELD
HOST = 0             # the node of the SENSOR frame announcing the host's receptions


def field_parts(kind: int, fields: tuple) -> list[tuple[int, int]]:
    """(arg, value) of the recv_field frames of a received frame: each field
    in 16-bit parts, low first, each a signed 16-bit number."""
    out = []
    for j, (v, (_name, size, _signed)) in enumerate(zip(fields, msg.SCHEMA[kind][1])):
        u = v & ((1 << (8 * size)) - 1)
        for part in range((size + 1) // 2):
            p = (u >> (16 * part)) & 0xFFFF
            out.append((j + 16 * part, p - 0x10000 if p & 0x8000 else p))
    return out


def join_parts(kind: int, parts: list[tuple[int, int]]) -> tuple:
    """The fields of a received frame from its recv_field (arg, value) pairs;
    ValueError when they do not make up a frame of `kind`."""
    spec = msg.SCHEMA[kind][1]
    raw = [0] * len(spec)
    seen = set()
    for arg, p in parts:
        j, part = arg % 16, arg // 16
        if j >= len(spec) or part >= (spec[j][1] + 1) // 2 or arg in seen:
            raise ValueError(f"recv_field {arg} is not a part of a {msg.SCHEMA[kind][0]} frame")
        seen.add(arg)
        raw[j] |= (p & 0xFFFF) << (16 * part)
    if len(seen) != sum((size + 1) // 2 for _n, size, _s in spec):
        raise ValueError(f"{len(seen)} recv_field frames do not make up a "
                         f"{msg.SCHEMA[kind][0]} frame")
    out = []
    for v, (_name, size, signed) in zip(raw, spec):
        v &= (1 << (8 * size)) - 1
        if signed and v >> (8 * size - 1):
            v -= 1 << (8 * size)
        out.append(v)
    return tuple(out)


class RecordingLink:
    """Wraps an engine Link (sim_backend/link.py) and keeps this tick's messages: those the host
    received (after the link's faults) and those it sent (before them). What
    the robots sent and received their bodies tape (Recorder.attach)."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.up: list[Message] = []
        self.down: list[Message] = []

    def robot_send(self, node: int, kind: int, fields: tuple) -> None:
        self.inner.robot_send(node, kind, fields)

    def robot_recv(self, node: int) -> tuple[int, tuple] | None:
        return self.inner.robot_recv(node)

    def poll(self, timeout: float) -> list[Message]:
        got = self.inner.poll(timeout)
        self.up.extend((node, kind, tuple(fields)) for node, kind, fields in got)
        return got

    def send(self, node: int, kind: int, fields: tuple) -> None:
        self.down.append((node, kind, tuple(fields)))
        self.inner.send(node, kind, fields)

    def bad_frames(self) -> dict[str, int]:
        """The wrapped link's refused frames (the per-tick trace counts them)."""
        return self.inner.bad_frames()

    def take(self) -> tuple[list[Message], list[Message]]:
        up, down = self.up, self.down
        self.up, self.down = [], []
        return up, down

    def close(self) -> None:
        self.inner.close()


def _taped(body: Any, method: str, query: int):
    orig = getattr(body, method)

    def wrapped() -> int:
        v = orig()
        if body.tape is not None:
            body.tape.append((query, 0, v))
        return v
    return wrapped


def portable_behaviour(ref: str, path: Path) -> tuple[str, str]:
    """(how a recording names its behaviour, the behaviour's NAME): an
    installed behaviour by its name; a folder by its path relative to the
    recording's own folder (both may move together; `replay --behaviour DIR`
    points at it otherwise), never an absolute path."""
    import os

    from sim_backend import registry
    b = registry.load(ref)
    if str(ref) in registry.names():
        return str(ref), b.name
    rel = os.path.relpath(b.folder, Path(path).resolve().parent)
    return Path(rel).as_posix(), b.name


class Recorder:
    """Writes one run, tick by tick, to a python-can log file (by suffix)."""

    def __init__(self, path: Path, scenario: Any, seed: int, link: str = "inproc") -> None:
        path = Path(path)
        record_format(path)
        self.path = path
        # the behaviour is also inside the scenario; written at the top level so
        # a reader of the sidecar sees at once which firmware made the frames;
        # portable: see portable_behaviour
        ref, name = portable_behaviour(scenario.behaviour, path)
        sc = scenario.to_dict()
        sc["behaviour"] = ref
        # a scenario run with another behaviour has no description of its own
        # (scenario.merge): say what ran
        sc["description"] = scenario.description or \
            f"{scenario.agents} robots, behaviour {name}"
        self.meta = {"scenario": sc, "seed": seed, "link": link,
                     "behaviour": ref, "behaviour_name": name,
                     "tick_seconds": TICK_SECONDS, "epoch": EPOCH, "format": FORMAT}
        try:
            self.writer = can.Logger(str(path))
        except OSError as err:
            raise UsageError(f"--record {path}: cannot write ({err.strerror or err})") \
                from None
        self.frames = 0
        self.sent: list[Message] = []     # the robots' messages this tick, as sent
        self._closed = False

    def attach(self, engine: Any) -> None:
        """Start taping every body of an engine (before its first tick)."""
        for b in engine.bodies:
            b.tape = []
            b.acts = []
            b.sent = self.sent
            b.x = _taped(b, "x", Q_X)
            b.y = _taped(b, "y", Q_Y)

    def write_tick(self, tick: int, bodies: list[Any], up: list[Message],
                   down: list[Message]) -> None:
        """One tick: the bodies' tapes, the robots' messages as sent (taped by
        the bodies), `up` the frames the host received, `down` its commands."""
        ts = EPOCH + tick * TICK_SECONDS
        frames = []
        t16 = tick & 0xFFFF
        for b in bodies:
            i = 0
            for q, arg, v in b.tape:
                if q == Q_RECV:
                    frames.append((b.node, msg.SENSOR, (t16, i & 0xFF, q, arg, 0)))
                    i += 1
                    for a, p in (field_parts(arg, v) if arg else ()):
                        frames.append((b.node, msg.SENSOR, (t16, i & 0xFF, Q_RECV_FIELD, a, p)))
                        i += 1
                    continue
                frames.append((b.node, msg.SENSOR, (t16, i & 0xFF, q, arg, v)))
                i += 1
            for i, (a, x, y) in enumerate(b.acts):
                frames.append((b.node, msg.ACTION, (t16, i & 0xFF, a, x, y)))
            b.tape.clear()
            b.acts.clear()
        frames.extend(self.sent)
        if list(up) != self.sent:
            frames.append((HOST, msg.SENSOR, (t16, 0, Q_RECV, len(up), 0)))
            frames.extend(up)
        self.sent.clear()
        frames.extend(down)
        for j, (node, kind, fields) in enumerate(frames):
            f = encode(node, kind, fields, timestamp=ts + j * 1e-6)
            f.channel = 0
            self.writer.on_message_received(f)
        self.frames += len(frames)

    def close(self, summary: dict | None = None) -> None:
        if self._closed:
            return
        self._closed = True
        self.writer.stop()
        meta = dict(self.meta, frames=self.frames)
        if summary is not None:
            meta["summary"] = summary
        meta_path(self.path).write_text(json.dumps(meta, sort_keys=True, indent=1) + "\n")

    def __enter__(self) -> "Recorder":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def recording_engine(sc: Any, seed: int, link: Any, recorder: Recorder):
    """An Engine whose every tick is written by `recorder`."""
    from sim_backend.engine import Engine

    class RecordingEngine(Engine):
        def step(self) -> None:
            super().step()
            up, down = self.link.take()
            recorder.write_tick(self.tick, self.bodies, up, down)

    eng = RecordingEngine(sc, seed, link=RecordingLink(link))
    recorder.attach(eng)
    return eng
