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

UP = "up"       # robot -> host
DOWN = "down"   # host -> robot(s)
CAPTURE = "capture"   # written into recordings, never sent on a bus

# The one table of the link's messages. Everything about a message is here;
# the compact SCHEMA below, the host codec's validation, the DBC (units,
# scaling, value tables, comments), the recorder and replay derive from it.
#
# (kind, name, direction, comment, fields); a field is
# (name, bytes, signed, divisor, unit, lo, hi, values):
#   physical value = raw / divisor, in `unit`;
#   lo..hi bound the raw value beyond its bytes (None: no further bound);
#   values names a value table: "states" and "models" come from the running
#   behaviour's spec.py, "query"/"action"/"probe" from firmware_logic/hal.py.
MESSAGES = (
    (HALT, "HALT", DOWN, "host -> robot(s): stop everything, beacon off (node 0: broadcast)",
     (("reason", 1, 0, 1, "", None, None, ""),)),
    (TRANSPORT, "TRANSPORT", DOWN,
     "host -> carrier: transport step number and displacement in patches",
     (("step", 1, 0, 1, "", 1, None, ""),
      ("dx", 1, 1, 1, "patch", -1, 1, ""),
      ("dy", 1, 1, 1, "patch", -1, 1, ""))),
    (ACK, "ACK", DOWN, "host -> robot: touch report seq journalled (seq 0: HELLO acknowledged)",
     (("seq", 1, 0, 1, "", None, None, ""),)),
    (TOUCH, "TOUCH", UP, "robot -> host: touch report, robot patch, touched segment, power",
     (("seq", 1, 0, 1, "", 1, None, ""),
      ("rx", 1, 1, 1, "patch", None, None, ""),
      ("ry", 1, 1, 1, "patch", None, None, ""),
      ("sx", 1, 1, 1, "patch", None, None, ""),
      ("sy", 1, 1, 1, "patch", None, None, ""),
      ("power", 2, 0, 100, "power", 1, None, ""))),
    (HELLO, "HELLO", UP, "robot -> host: announces the node, movement model, power, firmware version",
     (("model", 1, 0, 1, "", None, None, "models"),
      ("power", 2, 0, 100, "power", 1, None, ""),
      ("version", 1, 0, 1, "", 1, None, ""))),
    (HEARTBEAT, "HEARTBEAT", UP,
     "robot -> host: FSM state, pose in patches, heading degrees, last transport step done",
     (("state", 1, 0, 1, "", None, None, "states"),
      ("x", 2, 1, 256, "patch", None, None, ""),
      ("y", 2, 1, 256, "patch", None, None, ""),
      ("heading", 2, 0, 1, "deg", 0, 359, ""),
      ("step", 1, 0, 1, "", None, None, ""))),
    (SENSOR, "SENSOR", CAPTURE, "capture: one sensor reading the firmware took",
     (("tick", 2, 0, 1, "", None, None, ""),
      ("index", 1, 0, 1, "", None, None, ""),
      ("query", 1, 0, 1, "", 1, 9, "query"),
      ("arg", 2, 1, 1, "", None, None, ""),
      ("value", 2, 1, 1, "", None, None, ""))),
    (ACTION, "ACTION", CAPTURE, "capture: one action the firmware decided",
     (("tick", 2, 0, 1, "", None, None, ""),
      ("index", 1, 0, 1, "", None, None, ""),
      ("action", 1, 0, 1, "", 1, 4, "action"),
      ("a", 2, 1, 1, "", None, None, ""),
      ("b", 2, 1, 1, "", None, None, ""))),
)

# The sealed form of the link's reports (with keys, docs/protocol.md
# "Authenticated robot reports"): a keyed robot sends these 4 payload bytes,
# then a freshness byte and a 24-bit MAC, in place of the plain layout above
# (7 and 8 bytes leave no room for them). (kind, fields), a field as in
# MESSAGES. A field named as a plain one carries it (a Q8 field, divisor 256
# there, in whole units); `near` carries the robot patch as the index of
# (rx - sx, ry - sy) in NEAR; a plain field the sealed form lacks is the
# node's value of that name in its HELLO (TOUCH power), else 0 (HEARTBEAT
# heading). A behaviour's own report has no row here: sealed, each Q8 field
# travels in whole units, and it must then fit 4 bytes.
NEAR = ((-1, -1), (0, -1), (1, -1), (-1, 0), (1, 0), (-1, 1), (0, 1), (1, 1))
SEALED = (
    (TOUCH, (("seq", 1, 0, 1, "", 1, None, ""),
             ("sx", 1, 1, 1, "patch", None, None, ""),
             ("sy", 1, 1, 1, "patch", None, None, ""),
             ("near", 1, 0, 1, "", 0, 7, ""))),
    (HEARTBEAT, (("state", 1, 0, 1, "", None, None, "states"),
                 ("x", 1, 1, 1, "patch", None, None, ""),
                 ("y", 1, 1, 1, "patch", None, None, ""),
                 ("step", 1, 0, 1, "", None, None, ""))),
)

# kind -> (name, ((field, size in bytes, signed), ...)): what pack/unpack and
# the framing decoder need, derived from MESSAGES once at import
SCHEMA = {}
for _m in MESSAGES:
    _f = []
    for _x in _m[4]:
        _f.append((_x[0], _x[1], _x[2]))
    SCHEMA[_m[0]] = (_m[1], tuple(_f))


# kind codes a behaviour may give messages of its own (spec.MESSAGES, in the
# format of MESSAGES): every 4-bit kind the link's messages above leave free
LINK_KINDS = []
for _m in MESSAGES:
    LINK_KINDS.append(_m[0])
LINK_KINDS = tuple(LINK_KINDS)
FREE_KINDS = []
for _k in range(1, 16):
    if _k not in LINK_KINDS:
        FREE_KINDS.append(_k)
FREE_KINDS = tuple(FREE_KINDS)
# the messages of the behaviour in use (activate): kinds are per behaviour, so
# two behaviours may give the same free kind messages of their own
ACTIVE = []


def check(rows):
    """Refuse a behaviour's own messages that do not fit the link: each row is
    in MESSAGES' format, its kind one of FREE_KINDS and its name not a link
    message's, its direction UP or DOWN, its fields of 1 or 2 bytes, at most 6
    of them and 8 bytes in all; no kind or name twice. SchemaError names the
    message and what is wrong."""
    seen = {}
    for m in rows:
        kind = m[0]
        for link in MESSAGES:
            if link[0] == kind:
                raise SchemaError("message %s: kind %d is the link's %s; a behaviour's own "
                                  "messages use kinds %s" % (m[1], kind, link[1], free_text()))
            if link[1] == m[1]:
                raise SchemaError("message %s: the name is the link's (kind %d); pick "
                                  "another" % (m[1], link[0]))
        if kind not in FREE_KINDS:
            raise SchemaError("message %s: kind %s is not a 4-bit kind the link leaves "
                              "free (%s)" % (m[1], kind, free_text()))
        if kind in seen:
            raise SchemaError("kind %d is declared twice: %s and %s" % (kind, seen[kind], m[1]))
        for k in seen:
            if seen[k] == m[1]:
                raise SchemaError("message %s is declared twice: kinds %d and %d"
                                  % (m[1], k, kind))
        seen[kind] = m[1]
        if m[2] != UP and m[2] != DOWN:
            raise SchemaError("message %s: direction must be up or down" % m[1])
        size = 0
        for x in m[4]:
            if x[1] != 1 and x[1] != 2:
                raise SchemaError("message %s: field %s has %d bytes; 1 or 2 fit the "
                                  "link" % (m[1], x[0], x[1]))
            size += x[1]
        if size > 8 or len(m[4]) > 6:
            raise SchemaError("message %s: %d fields, %d bytes; at most 6 fields in "
                              "8 bytes fit a CAN frame" % (m[1], len(m[4]), size))


def free_text():
    """FREE_KINDS as runs ("7-9, 12-15"), for messages and the guide."""
    out = []
    i = 0
    while i < len(FREE_KINDS):
        j = i
        while j + 1 < len(FREE_KINDS) and FREE_KINDS[j + 1] == FREE_KINDS[j] + 1:
            j += 1
        if j == i:
            out.append("%d" % FREE_KINDS[i])
        else:
            out.append("%d-%d" % (FREE_KINDS[i], FREE_KINDS[j]))
        i = j + 1
    return ", ".join(out)


def activate(rows):
    """Make `rows` (a behaviour's spec.MESSAGES, checked) the messages of the
    behaviour in use, beside the link's: pack/unpack, rows() and spec() then
    know them, and no longer the previous behaviour's (the board does this
    once at start-up; the host whenever it puts a behaviour to use)."""
    rows = tuple(rows)
    if rows == tuple(ACTIVE):
        return
    check(rows)
    while ACTIVE:
        del SCHEMA[ACTIVE.pop()[0]]
    for m in rows:
        f = []
        for x in m[4]:
            f.append((x[0], x[1], x[2]))
        SCHEMA[m[0]] = (m[1], tuple(f))
        ACTIVE.append(m)


def rows():
    """Every message in use: the link's, then the active behaviour's."""
    return MESSAGES + tuple(ACTIVE)


def spec(kind):
    """The full declaration of a message kind (a row of rows())."""
    for m in rows():
        if m[0] == kind:
            return m
    raise SchemaError("unknown message kind %d" % kind)


FIRMWARE_VERSION = 1

# host-side helpers exempt from the step-path allocation rules (docs/subset.md)
SUBSET_SETUP = ("split_id", "spec", "check", "free_text", "activate", "rows")


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
