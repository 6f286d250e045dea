"""The message schema of firmware_logic.messages exported as a DBC (cantools).

The node id is part of the identifier (kind << 7 | node), so every (kind, node)
pair is its own DBC message, named KIND_NODE (e.g. TOUCH_5, ACK_0). Host
commands exist for node 0 (broadcast) and every robot; robot reports and
capture frames for robots 1..max_node, plus SENSOR_0: a recording's count of
the frames the host received (bridge/record/recorder.py).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from firmware_logic import messages as msg

from bridge.links.codec import schema, value_tables


def build(max_node: int = msg.MAX_NODE, behaviour: Any = None):
    """A cantools Database of the link's messages and the behaviour's own: physical
    units and scaling, value tables (the behaviour's states and models,
    default the thesis's), comments. Never another behaviour's messages:
    kinds are per behaviour."""
    from cantools.database.can import Database, Message, Node, Signal
    from cantools.database.conversion import BaseConversion

    from sim_backend import registry
    b = behaviour if behaviour is not None else registry.load()
    tables = value_tables(b)
    s = schema(b)                 # the link's messages and this behaviour's own
    rows = s.rows

    if not 1 <= max_node <= msg.MAX_NODE:
        raise ValueError(f"max_node must be 1..{msg.MAX_NODE}, not {max_node}")
    names = ["HOST"] + [f"R{n}" for n in range(1, max_node + 1)]
    nodes = [Node(name, comment=None) for name in names]
    messages = []
    for kind, kname, _direction, comment, spec in sorted(rows):
        first = 0 if kind in s.host_kinds or kind == msg.SENSOR else 1
        for node in range(first, max_node + 1):
            signals = []
            pos = 0
            for field, size, signed, divisor, unit, flo, fhi, values in spec:
                bits = size * 8
                lo = -(1 << (bits - 1)) if signed else 0
                hi = (1 << (bits - 1)) - 1 if signed else (1 << bits) - 1
                lo = lo if flo is None else flo
                hi = hi if fhi is None else fhi
                conv = BaseConversion.factory(scale=1 / divisor, offset=0,
                                              choices=tables[values] if values else None,
                                              is_float=False)
                signals.append(Signal(field, start=pos * 8, length=bits,
                                      byte_order="little_endian", is_signed=bool(signed),
                                      conversion=conv, minimum=lo / divisor,
                                      maximum=hi / divisor, unit=unit or None))
                pos += size
            sender = "HOST" if kind in s.host_kinds or node == 0 else f"R{node}"
            messages.append(Message(frame_id=msg.can_id(kind, node), name=f"{kname}_{node}",
                                    length=pos, signals=signals, senders=[sender],
                                    comment=comment, is_extended_frame=False))
    return Database(messages=messages, nodes=nodes, version=str(msg.FIRMWARE_VERSION))


def dbc_text(max_node: int = msg.MAX_NODE, behaviour: Any = None) -> str:
    return build(max_node, behaviour).as_dbc_string()


def write(path: Path, max_node: int = msg.MAX_NODE, behaviour: Any = None) -> int:
    """Write the DBC of `behaviour` (default: the thesis) to `path`; return the
    number of messages."""
    db = build(max_node, behaviour)
    with open(path, "w", newline="") as f:
        f.write(db.as_dbc_string())
    return len(db.messages)
