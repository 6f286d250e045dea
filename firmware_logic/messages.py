"""The one message schema shared by every link (in-process, CAN, serial).

Every message fits a classic CAN frame: an 11-bit identifier made of a 4-bit
kind (which is also its bus priority: lower wins arbitration) and a 7-bit node
id, and at most 8 data bytes, little endian. Node 0 is the host; a command
addressed to node 0 is a broadcast. Robot nodes are 1..127.

Fields are integers; payloads are packed by hand because the firmware may not
import `struct` (it must run unchanged on MicroPython and on CPython).
"""

# kind codes; the order is the arbitration priority on CAN
HALT = 1        # host -> robot(s): stop everything, beacon off
TRANSPORT = 2   # host -> carrier: step number, dx, dy (patches)
ACK = 3         # host -> robot: touch report `seq` is journalled
TOUCH = 4       # robot -> host: seq, robot patch, touched segment, power
HELLO = 5       # robot -> host: announces a node, its model and power
HEARTBEAT = 6   # robot -> host: state, pose (Q8), heading, last transport step
SENSOR = 10     # capture: one sensor reading the firmware took
ACTION = 11     # capture: one action the firmware decided

HOST = 0
MAX_NODE = 127

# kind -> (name, ((field, size in bytes, signed), ...))
SCHEMA = {
    HALT: ("HALT", (("reason", 1, 0),)),
    TRANSPORT: ("TRANSPORT", (("step", 1, 0), ("dx", 1, 1), ("dy", 1, 1))),
    ACK: ("ACK", (("seq", 1, 0),)),
    TOUCH: ("TOUCH", (("seq", 1, 0), ("rx", 1, 1), ("ry", 1, 1),
                      ("sx", 1, 1), ("sy", 1, 1), ("power", 2, 0))),
    HELLO: ("HELLO", (("model", 1, 0), ("power", 2, 0), ("version", 1, 0))),
    HEARTBEAT: ("HEARTBEAT", (("state", 1, 0), ("x", 2, 1), ("y", 2, 1),
                              ("heading", 2, 0), ("step", 1, 0))),
    SENSOR: ("SENSOR", (("tick", 2, 0), ("index", 1, 0), ("query", 1, 0),
                        ("arg", 2, 1), ("value", 2, 1))),
    ACTION: ("ACTION", (("tick", 2, 0), ("index", 1, 0), ("action", 1, 0),
                        ("a", 2, 1), ("b", 2, 1))),
}

FIRMWARE_VERSION = 1

# host-side helpers exempt from the step-path allocation rules (docs/subset.md)
SUBSET_SETUP = ("split_id",)


class SchemaError(ValueError):
    pass


def can_id(kind, node):
    return (kind << 7) | (node & 0x7F)


def split_id(arbitration_id):
    """(kind, node) of an 11-bit identifier."""
    return (arbitration_id >> 7) & 0x0F, arbitration_id & 0x7F


def fields(kind):
    return SCHEMA[kind][1]


def dlc(kind):
    n = 0
    for f in SCHEMA[kind][1]:
        n += f[1]
    return n


def pack(kind, args, buf):
    """Write args (a sequence of ints) into buf (>= 8 bytes); return the DLC.

    Raises SchemaError naming the field when a value does not fit.
    """
    spec = SCHEMA.get(kind)
    if spec is None:
        raise SchemaError("unknown message kind %d" % kind)
    pos = 0
    i = 0
    for name, size, signed in spec[1]:
        v = args[i]
        bits = size * 8
        if signed:
            lo = -(1 << (bits - 1))
            hi = (1 << (bits - 1)) - 1
        else:
            lo = 0
            hi = (1 << bits) - 1
        if v < lo or v > hi:
            raise SchemaError("%s.%s=%d outside %d..%d" % (spec[0], name, v, lo, hi))
        if v < 0:
            v += 1 << bits
        j = 0
        while j < size:
            buf[pos + j] = (v >> (8 * j)) & 0xFF
            j += 1
        pos += size
        i += 1
    return pos


def unpack(kind, data, out):
    """Decode data into out (a list with room for 6 ints); return the field count.

    Raises SchemaError on an unknown kind or a wrong length.
    """
    spec = SCHEMA.get(kind)
    if spec is None:
        raise SchemaError("unknown message kind %d" % kind)
    need = dlc(kind)
    if len(data) != need:
        raise SchemaError("%s needs %d data bytes, got %d" % (spec[0], need, len(data)))
    pos = 0
    i = 0
    for name, size, signed in spec[1]:
        v = 0
        j = 0
        while j < size:
            v |= data[pos + j] << (8 * j)
            j += 1
        if signed and v >= 1 << (size * 8 - 1):
            v -= 1 << (size * 8)
        out[i] = v
        pos += size
        i += 1
    return i
