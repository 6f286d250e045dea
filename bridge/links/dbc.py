"""The message schema of firmware_logic.messages exported as a DBC (cantools).

The node id is part of the identifier (kind << 7 | node), so every (kind, node)
pair is its own DBC message, named KIND_NODE (e.g. TOUCH_5, ACK_0). Host
commands exist for node 0 (broadcast) and every robot; robot reports and
capture frames for robots 1..max_node, plus SENSOR_0: a recording's count of
the frames the host received (bridge/record/recorder.py).

`keyed=True` describes a keyed bus (`--keys`, bridge/links/secoc.py) instead:
every host command and robot report travels sealed in 8 bytes, laid out as
secoc.keyed_layout says (payload fields, then `fv`, the freshness value's low
bytes, and `mac`, the 24-bit MAC, both big-endian); host commands exist only
for robots 1..max_node (a keyed host sends a broadcast once per robot, and
the robots refuse one on the bus). Capture frames are never sealed.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from firmware_logic import messages as msg

from bridge.links.codec import schema, value_tables


# what the keyed layouts' freshness and MAC signals are, by message direction
FV_COMMENT = {
    msg.DOWN: "freshness: the low bytes of the host's counter for this robot (big-endian)",
    "hello": "freshness: the low byte of the robot's floor block (its last host counter >> 8)",
    msg.UP: "freshness: the low byte of r, the robot's count of reports since its last "
            "host command",
}
MAC_COMMENT = "AES-128-CMAC truncated to 24 bits (big-endian)"


def _signals(spec: tuple, tables: dict, Signal: Any, BaseConversion: Any) -> tuple[list, int]:
    """The signals of the fields `spec` from byte 0, little endian; and their bytes."""
    signals = []
    pos = 0
    for field, size, signed, divisor, unit, flo, fhi, values in spec:
        bits = size * 8
        lo = -(1 << (bits - 1)) if signed else 0
        hi = (1 << (bits - 1)) - 1 if signed else (1 << bits) - 1
        lo = lo if flo is None else flo
        hi = hi if fhi is None else fhi
        choices = tables[values] if values else tables.get("near") if field == "near" else None
        conv = BaseConversion.factory(scale=1 / divisor, offset=0, choices=choices,
                                      is_float=False)
        signals.append(Signal(field, start=pos * 8, length=bits,
                              byte_order="little_endian", is_signed=bool(signed),
                              conversion=conv, minimum=lo / divisor,
                              maximum=hi / divisor, unit=unit or None))
        pos += size
    return signals, pos


def build(max_node: int = msg.MAX_NODE, behaviour: Any = None, keyed: bool = False):
    """A cantools Database of the link's messages and the behaviour's own: physical
    units and scaling, value tables (the behaviour's states and models,
    default the thesis's), comments. Never another behaviour's messages:
    kinds are per behaviour. `keyed`: the sealed layouts of a keyed bus."""
    from cantools.database.can import Database, Message, Node, Signal
    from cantools.database.conversion import BaseConversion

    from bridge.links import secoc
    from sim_backend import registry
    b = behaviour if behaviour is not None else registry.load()
    tables: dict = dict(value_tables(b))
    if keyed:   # a sealed TOUCH's `near`: the robot patch as an index into messages.NEAR
        tables["near"] = {i: f"rx-sx={dx} ry-sy={dy}" for i, (dx, dy) in enumerate(msg.NEAR)}
    s = schema(b)                 # the link's messages and this behaviour's own
    rows = s.rows

    if not 1 <= max_node <= msg.MAX_NODE:
        raise ValueError(f"max_node must be 1..{msg.MAX_NODE}, not {max_node}")
    names = ["HOST"] + [f"R{n}" for n in range(1, max_node + 1)]
    nodes = [Node(name, comment=None) for name in names]
    messages = []
    for row in sorted(rows):
        kind, kname, direction, comment, spec = row
        layout = secoc.keyed_layout(row) if keyed else None
        first = 0 if kind in s.host_kinds or kind == msg.SENSOR else 1
        if layout is not None:
            first = 1                 # no broadcast on a keyed bus
            taken = {f[0] for f in layout[0]} & {"fv", "mac"}
            if taken:
                raise ValueError(f"message {kname}: a field named {sorted(taken)[0]!r} "
                                 "clashes with the keyed DBC's freshness or MAC signal")
            fields, n, k = layout
            comment = f"{comment} (sealed: payload {n} bytes, fv {k}, mac {secoc.MAC_BYTES})"
        for node in range(first, max_node + 1):
            if layout is None:
                signals, length = _signals(spec, tables, Signal, BaseConversion)
            else:
                signals, _ = _signals(fields, tables, Signal, BaseConversion)
                what = "hello" if kind == msg.HELLO else direction
                signals.append(Signal("fv", start=n * 8 + 7, length=8 * k,
                                      byte_order="big_endian", is_signed=False,
                                      minimum=0, maximum=(1 << (8 * k)) - 1,
                                      comment=FV_COMMENT[what]))
                signals.append(Signal("mac", start=(n + k) * 8 + 7,
                                      length=8 * secoc.MAC_BYTES, byte_order="big_endian",
                                      is_signed=False, minimum=0,
                                      maximum=(1 << (8 * secoc.MAC_BYTES)) - 1,
                                      comment=MAC_COMMENT))
                length = n + k + secoc.MAC_BYTES
            sender = "HOST" if kind in s.host_kinds or node == 0 else f"R{node}"
            messages.append(Message(frame_id=msg.can_id(kind, node), name=f"{kname}_{node}",
                                    length=length, signals=signals, senders=[sender],
                                    comment=comment, is_extended_frame=False))
    return Database(messages=messages, nodes=nodes, version=str(msg.FIRMWARE_VERSION))


def dbc_text(max_node: int = msg.MAX_NODE, behaviour: Any = None, keyed: bool = False) -> str:
    return build(max_node, behaviour, keyed).as_dbc_string()


def write(path: Path, max_node: int = msg.MAX_NODE, behaviour: Any = None,
          keyed: bool = False) -> int:
    """Write the DBC of `behaviour` (default: the thesis) to `path`, `keyed`: of
    a keyed bus; return the number of messages."""
    db = build(max_node, behaviour, keyed)
    with open(path, "w", newline="") as f:
        f.write(db.as_dbc_string())
    return len(db.messages)
