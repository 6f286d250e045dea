"""The message schema of firmware_logic.messages exported as a DBC (cantools).

The node id is part of the identifier (kind << 7 | node), so every (kind, node)
pair is its own DBC message, named KIND_NODE (e.g. TOUCH_5, ACK_0). Host
commands exist for node 0 (broadcast) and every robot; robot reports and
capture frames for robots 1..max_node.
"""

from __future__ import annotations

from pathlib import Path

from firmware_logic import messages as msg

from bridge.links.codec import HOST_KINDS

COMMENTS = {
    msg.HALT: "host -> robot(s): stop, beacon off (node 0: broadcast)",
    msg.TRANSPORT: "host -> carrier: transport step number and displacement in patches",
    msg.ACK: "host -> robot: touch report seq journalled (seq 0: HELLO acknowledged)",
    msg.TOUCH: "robot -> host: touch report, robot patch, touched segment, power (1/100)",
    msg.HELLO: "robot -> host: announces the node, movement model, power, firmware version",
    msg.HEARTBEAT: "robot -> host: FSM state, pose Q8 patches, heading degrees, last step done",
    msg.SENSOR: "capture: one sensor reading (query 1 probe, 2 field_ahead, 3 field_here, "
                "4 uphill, 5 holding, 6 recv, 7 x, 8 y)",
    msg.ACTION: "capture: one action (1 forward, 2 claim, 3 carry, 4 beacon)",
}


def build(max_node: int = msg.MAX_NODE):
    """A cantools Database of every message the schema defines."""
    from cantools.database.can import Database, Message, Node, Signal

    if not 1 <= max_node <= msg.MAX_NODE:
        raise ValueError(f"max_node must be 1..{msg.MAX_NODE}, not {max_node}")
    names = ["HOST"] + [f"R{n}" for n in range(1, max_node + 1)]
    nodes = [Node(name, comment=None) for name in names]
    messages = []
    for kind in sorted(msg.SCHEMA):
        kname, spec = msg.SCHEMA[kind]
        first = 0 if kind in HOST_KINDS else 1
        for node in range(first, max_node + 1):
            signals = []
            pos = 0
            for field, size, signed in spec:
                bits = size * 8
                lo = -(1 << (bits - 1)) if signed else 0
                hi = (1 << (bits - 1)) - 1 if signed else (1 << bits) - 1
                signals.append(Signal(field, start=pos * 8, length=bits,
                                      byte_order="little_endian", is_signed=bool(signed),
                                      minimum=lo, maximum=hi))
                pos += size
            sender = "HOST" if kind in HOST_KINDS else f"R{node}"
            messages.append(Message(frame_id=msg.can_id(kind, node), name=f"{kname}_{node}",
                                    length=pos, signals=signals, senders=[sender],
                                    comment=COMMENTS[kind], is_extended_frame=False))
    return Database(messages=messages, nodes=nodes, version=str(msg.FIRMWARE_VERSION))


def dbc_text(max_node: int = msg.MAX_NODE) -> str:
    return build(max_node).as_dbc_string()


def write(path: Path, max_node: int = msg.MAX_NODE) -> int:
    """Write the DBC to `path`; return the number of messages."""
    db = build(max_node)
    with open(path, "w", newline="") as f:
        f.write(db.as_dbc_string())
    return len(db.messages)
