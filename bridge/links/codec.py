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
from typing import Callable

import can

from firmware_logic import messages as msg

log = logging.getLogger(__name__)

Message = tuple[int, int, tuple]   # (node, kind, fields)

HOST_KINDS = frozenset((msg.HALT, msg.TRANSPORT, msg.ACK))
ROBOT_KINDS = frozenset((msg.TOUCH, msg.HELLO, msg.HEARTBEAT))
CAPTURE_KINDS = frozenset((msg.SENSOR, msg.ACTION))

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


def _ok_halt(f: tuple) -> bool:
    return True


def _ok_transport(f: tuple) -> bool:
    return f[0] >= 1 and -1 <= f[1] <= 1 and -1 <= f[2] <= 1


def _ok_ack(f: tuple) -> bool:
    return True


def _ok_touch(f: tuple) -> bool:
    return f[0] >= 1 and f[5] >= 1 and -1 <= f[3] - f[1] <= 1 and -1 <= f[4] - f[2] <= 1


def _ok_hello(f: tuple) -> bool:
    return f[0] in (1, 2) and f[1] >= 1 and f[2] >= 1


def _ok_heartbeat(f: tuple) -> bool:
    return f[0] <= 5 and f[3] < 360


def _ok_sensor(f: tuple) -> bool:
    return 1 <= f[2] <= 8


def _ok_action(f: tuple) -> bool:
    return 1 <= f[2] <= 4


# field ranges beyond what the byte sizes already bound (docs/protocol.md)
VALID: dict[int, Callable[[tuple], bool]] = {
    msg.HALT: _ok_halt, msg.TRANSPORT: _ok_transport, msg.ACK: _ok_ack,
    msg.TOUCH: _ok_touch, msg.HELLO: _ok_hello, msg.HEARTBEAT: _ok_heartbeat,
    msg.SENSOR: _ok_sensor, msg.ACTION: _ok_action,
}


def struct_for(kind: int) -> struct.Struct:
    codes = {(1, 0): "B", (1, 1): "b", (2, 0): "H", (2, 1): "h"}
    return struct.Struct("<" + "".join(codes[(size, signed)]
                                       for _, size, signed in msg.fields(kind)))


_STRUCTS = {k: struct_for(k) for k in msg.SCHEMA}
_DLC = {k: msg.dlc(k) for k in msg.SCHEMA}
# arbitration id -> (node, kind, Struct, dlc)
_TABLE = {msg.can_id(k, n): (n, k, _STRUCTS[k], _DLC[k])
          for k in msg.SCHEMA for n in range(msg.MAX_NODE + 1)}


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

    def __init__(self, side: str, bad: BadFrames | None = None) -> None:
        if side not in ("host", "robot"):
            raise ValueError(f"side must be 'host' or 'robot', not {side!r}")
        self.side = side
        self.accept = ROBOT_KINDS if side == "host" else HOST_KINDS
        self.bad = bad if bad is not None else BadFrames(side)
        # fast path: id -> (node, kind, unpack, dlc, valid) for what this side accepts
        self.fast = {i: (n, k, st.unpack, dlc, VALID[k]) for i, (n, k, st, dlc) in _TABLE.items()
                     if k in self.accept and not (k in ROBOT_KINDS and n == msg.HOST)}

    def decode(self, frame: can.Message) -> Message | None:
        """The message in `frame`, or None when it is bad or not for this side."""
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
        entry = _TABLE.get(frame.arbitration_id)
        if entry is None:
            bad.add(UNKNOWN_ID, frame)
            return None
        node, kind, st, dlc = entry
        if kind in CAPTURE_KINDS or (self.side == "robot" and kind in ROBOT_KINDS):
            return None
        if kind not in self.accept:
            bad.add(WRONG_DIRECTION, frame)
            return None
        data = frame.data
        if len(data) != dlc:
            bad.add(WRONG_DLC, frame)
            return None
        f = st.unpack(data)
        if (kind in ROBOT_KINDS and node == msg.HOST) or not VALID[kind](f):
            bad.add(OUT_OF_RANGE, frame)
            return None
        return node, kind, f

    def decode_capture(self, frame: can.Message) -> Message | None:
        """Any well-formed frame of the schema, capture frames included (replay)."""
        entry = _TABLE.get(frame.arbitration_id)
        if entry is None or frame.is_extended_id or frame.is_remote_frame:
            self.bad.add(UNKNOWN_ID, frame)
            return None
        node, kind, st, dlc = entry
        if len(frame.data) != dlc:
            self.bad.add(WRONG_DLC, frame)
            return None
        return node, kind, st.unpack(frame.data)
