"""CAN frames <-> messages of firmware_logic.messages, with bad-frame accounting.

Encoding uses the firmware's own `messages.pack`, so the bytes on the bus are
the ones a MicroPython robot produces. Decoding on the host uses a table
built once from the schema (one lookup per frame; struct for speed) and then
checks each field against the ranges below. A frame that fails is never
passed on: it is counted by kind of fault and each kind is logged once.
"""

from __future__ import annotations

import logging
import struct
from typing import Any, Callable

import can

from firmware_logic import hal
from sim_backend import registry
from firmware_logic import messages as msg

log = logging.getLogger(__name__)

Message = tuple[int, int, tuple]   # (node, kind, fields)

# by direction, for the behaviour in use (activate() keeps them in step)
HOST_KINDS: set[int] = set()
ROBOT_KINDS: set[int] = set()
CAPTURE_KINDS: set[int] = set()

# fault kinds, the keys of BadFrames.counts
EXTENDED = "extended id"
REMOTE = "remote frame"
ERROR = "error frame"
FD = "fd frame"
UNKNOWN_ID = "unknown id"
WRONG_DLC = "wrong dlc"
OUT_OF_RANGE = "out of range"
UNANNOUNCED = "unannounced node"
WRONG_DIRECTION = "wrong direction"
FAULTS = (EXTENDED, REMOTE, ERROR, FD, UNKNOWN_ID, WRONG_DLC, OUT_OF_RANGE,
          UNANNOUNCED, WRONG_DIRECTION)


def value_tables(behaviour: Any = None) -> dict[str, dict[int, str]]:
    """Value tables by the names messages.MESSAGES uses: the behaviour's states
    and models (default: the one in use) and the HAL's query/action codes."""
    b = behaviour if behaviour is not None else registry.active()
    return {
        "states": dict(enumerate(b.spec.STATES)),
        "models": dict(b.spec.MODELS),
        "query": {i: n for i, n in enumerate(hal.QUERY_NAMES) if n},
        "action": {i: n for i, n in enumerate(hal.ACTION_NAMES) if n},
    }


def field_checks(row: tuple, tables: dict[str, dict[int, str]]) -> list[tuple[int, Any, Any, Any]]:
    """(index, lo, hi, allowed values) for every field of the message `row`
    (a row of messages.MESSAGES or a spec.MESSAGES) that the declaration
    bounds beyond its byte size."""
    out = []
    for i, (_name, _size, _signed, _div, _unit, lo, hi, values) in enumerate(row[4]):
        allowed = frozenset(tables[values]) if values else None
        if lo is not None or hi is not None or allowed is not None:
            out.append((i, lo, hi, allowed))
    return out


def _adjacent(f: tuple) -> bool:
    # the one cross-field rule: a touched segment is next to the robot's patch
    return -1 <= f[3] - f[1] <= 1 and -1 <= f[4] - f[2] <= 1


def validator(row: tuple, tables: dict[str, dict[int, str]]) -> Callable[[tuple], bool]:
    checks = field_checks(row, tables)
    extra = _adjacent if row[0] == msg.TOUCH else None

    def ok(f: tuple) -> bool:
        for i, lo, hi, allowed in checks:
            v = f[i]
            if (lo is not None and v < lo) or (hi is not None and v > hi) or \
                    (allowed is not None and v not in allowed):
                return False
        return extra is None or extra(f)
    return ok


# field ranges beyond what the byte sizes already bound (docs/protocol.md),
# of the behaviour in use (activate() keeps it in step)
VALID: dict[int, Callable[[tuple], bool]] = {}


def struct_for(row: tuple) -> struct.Struct:
    codes = {(1, 0): "B", (1, 1): "b", (2, 0): "H", (2, 1): "h"}
    return struct.Struct("<" + "".join(codes[(f[1], f[2])] for f in row[4]))


class Schema:
    """One behaviour's view of the bus: the link's messages and its own
    (spec.MESSAGES), validated against its own states and models. Kinds are
    per behaviour: two behaviours may give one free kind different messages."""

    def __init__(self, behaviour: Any) -> None:
        self.behaviour = behaviour
        self.rows = msg.MESSAGES + behaviour.messages
        tables = value_tables(behaviour)
        self.by_direction: dict[Any, set[int]] = {msg.DOWN: set(), msg.UP: set(), msg.CAPTURE: set()}
        self.valid: dict[int, Callable[[tuple], bool]] = {}
        self.names: dict[int, str] = {}
        # arbitration id -> (node, kind, Struct, dlc)
        self.table: dict[int, tuple[int, int, struct.Struct, int]] = {}
        for row in self.rows:
            k = row[0]
            self.by_direction[row[2]].add(k)
            self.valid[k] = validator(row, tables)
            self.names[k] = row[1]
            st = struct_for(row)
            for n in range(msg.MAX_NODE + 1):
                self.table[msg.can_id(k, n)] = (n, k, st, st.size)

    @property
    def host_kinds(self) -> set[int]:
        return self.by_direction[msg.DOWN]

    @property
    def robot_kinds(self) -> set[int]:
        return self.by_direction[msg.UP]

    @property
    def capture_kinds(self) -> set[int]:
        return self.by_direction[msg.CAPTURE]


_SCHEMAS: dict[str, Schema] = {}


def schema(behaviour: Any = None) -> Schema:
    """The schema of `behaviour` (default: the one in use), built once."""
    b = behaviour if behaviour is not None else registry.active()
    key = b.module_name
    got = _SCHEMAS.get(key)
    if got is None or got.behaviour.spec is not b.spec:
        got = _SCHEMAS[key] = Schema(b)
    return got


_CURRENT: list[Schema] = []


def current() -> Schema:
    """The schema of the behaviour in use; the module's HOST_KINDS,
    ROBOT_KINDS, CAPTURE_KINDS and VALID follow it."""
    s = schema()
    if not _CURRENT or _CURRENT[0] is not s:
        _CURRENT[:] = [s]
        for mine, theirs in ((HOST_KINDS, s.host_kinds), (ROBOT_KINDS, s.robot_kinds),
                             (CAPTURE_KINDS, s.capture_kinds)):
            mine.clear()
            mine.update(theirs)
        VALID.clear()
        VALID.update(s.valid)
    return s


def activate(behaviour: Any) -> Schema:
    """Put `behaviour` in use (registry.Behaviour.activate) and return its schema."""
    behaviour.activate()
    return current()


def refresh() -> None:
    """Follow the behaviour in use (kept for callers that only need the
    module-level tables in step)."""
    current()


refresh()


def encode(node: int, kind: int, fields: tuple, timestamp: float = 0.0) -> can.Message:
    """One classic CAN frame for a message, packed by the firmware's codec."""
    buf = bytearray(8)
    n = msg.pack(kind, fields, buf)
    return can.Message(arbitration_id=msg.can_id(kind, node), is_extended_id=False,
                       data=bytes(buf[:n]), dlc=n, timestamp=timestamp)


class BadFrames:
    """Counts dropped frames by kind of fault; logs the first of each kind."""

    def __init__(self, where: str) -> None:
        self.where = where
        self.counts: dict[str, int] = {}

    def add(self, fault: str, frame: object = None) -> None:
        n = self.counts.get(fault, 0)
        self.counts[fault] = n + 1
        if n == 0:
            log.warning("%s: dropping bad frame (%s): %s; further ones of this kind "
                        "are only counted", self.where, fault, frame)

    def total(self) -> int:
        return sum(self.counts.values())


class Decoder:
    """Validating frame decoder for one side of the bus.

    side "host" accepts robot reports; "robot" accepts host commands. Capture
    frames (SENSOR, ACTION) are ignored silently by both, and so are other
    robots' reports on the robots' side (normal on a shared bus); a host
    command seen by the host is counted as a bad frame (wrong direction).
    """

    def __init__(self, side: str, bad: BadFrames | None = None, behaviour: Any = None) -> None:
        if side not in ("host", "robot"):
            raise ValueError(f"side must be 'host' or 'robot', not {side!r}")
        self.side = side
        self.bad = bad if bad is not None else BadFrames(side)
        # a decoder made for one behaviour keeps its schema; otherwise it
        # follows the behaviour in use (a link is often made before the
        # engine that activates its behaviour)
        self.fixed = schema(behaviour) if behaviour is not None else None
        s = self.fixed if self.fixed is not None else current()
        self.bound: Any = registry._ACTIVE      # the behaviour in use when it last bound
        self._use(s)

    def _bind(self) -> None:
        s = self.fixed if self.fixed is not None else current()
        self.bound = registry._ACTIVE
        if s is not self.schema:
            self._use(s)

    def _use(self, s: Schema) -> None:
        self.schema = s
        self.accept = s.robot_kinds if self.side == "host" else s.host_kinds
        # fast path: id -> (node, kind, unpack, dlc, valid) for what this side accepts
        self.fast = {i: (n, k, st.unpack, dlc, s.valid[k]) for i, (n, k, st, dlc) in s.table.items()
                     if k in self.accept and not (k in s.robot_kinds and n == msg.HOST)}

    def decode(self, frame: can.Message) -> Message | None:
        """The message in `frame`, or None when it is bad or not for this side."""
        if self.bound is not registry._ACTIVE and self.fixed is None:
            self._bind()
        if not (frame.is_error_frame or frame.is_extended_id or frame.is_remote_frame
                or frame.is_fd):
            entry = self.fast.get(frame.arbitration_id)
            if entry is not None:
                data = frame.data
                if len(data) == entry[3]:
                    f = entry[2](data)
                    if entry[4](f):
                        return entry[0], entry[1], f
        return self._classify(frame)

    def _classify(self, frame: can.Message) -> Message | None:
        """The slow path: say why a frame is not passed on (or pass it on)."""
        bad = self.bad
        if frame.is_error_frame:
            bad.add(ERROR, frame)
            return None
        if frame.is_extended_id:
            bad.add(EXTENDED, frame)
            return None
        if frame.is_remote_frame:
            bad.add(REMOTE, frame)
            return None
        if frame.is_fd:
            bad.add(FD, frame)
            return None
        s = self.schema
        entry = s.table.get(frame.arbitration_id)
        if entry is None:
            bad.add(UNKNOWN_ID, frame)
            return None
        node, kind, st, dlc = entry
        if kind in s.capture_kinds or (self.side == "robot" and kind in s.robot_kinds):
            return None
        if kind not in self.accept:
            bad.add(WRONG_DIRECTION, frame)
            return None
        data = frame.data
        if len(data) != dlc:
            bad.add(WRONG_DLC, frame)
            return None
        f = st.unpack(data)
        if (kind in s.robot_kinds and node == msg.HOST) or not s.valid[kind](f):
            bad.add(OUT_OF_RANGE, frame)
            return None
        return node, kind, f

    def decode_capture(self, frame: can.Message) -> Message | None:
        """Any well-formed frame of the schema, capture frames included (replay)."""
        if self.bound is not registry._ACTIVE and self.fixed is None:
            self._bind()
        entry = self.schema.table.get(frame.arbitration_id)
        if entry is None or frame.is_extended_id or frame.is_remote_frame:
            self.bad.add(UNKNOWN_ID, frame)
            return None
        node, kind, st, dlc = entry
        if len(frame.data) != dlc:
            self.bad.add(WRONG_DLC, frame)
            return None
        return node, kind, st.unpack(frame.data)
