"""The narrow hardware abstraction a robot body offers the firmware.

A body (the simulator's, a Khepera II driven over RS-232, a GoGo Board, a
MicroPython board's pins) implements these methods; the FSM calls nothing
else. All values are small ints: positions are Q8 patches
(firmware_logic/fixedpoint.py), headings whole degrees, 0 = north.

Sensing (answered from the world as it stood at the start of the tick):
    x(), y()                 -> own position, Q8
    probe(heading)           -> NOTHING / OBJECT / CLAIMED / ROBOT / WALL for
                                the patch one patch ahead along `heading`
    field_ahead(heading)     -> potential-field strength one patch ahead
    field_here()             -> field strength at the own patch
    uphill()                 -> heading (multiple of 45) to the strongest
                                neighbouring patch if stronger than here, else -1
    holding()                -> 1 if the last claim succeeded and is held
Acting (at most one of forward / claim / carry per tick):
    forward(heading, step)   -> move `step` (Q8) along `heading`
    claim(heading)           -> grip the segment one patch ahead
    carry(dx, dy)            -> move with the object by whole patches
    beacon(on)               -> field source off (BEACON_OFF), on (BEACON_ON), or
                                on as a leader's (BEACON_LEADER: the world also
                                keeps its own patch's field at 10, Appendix A's
                                `set field 10`)
Messages (firmware_logic/messages.py):
    send(kind, a0, a1, a2, a3, a4, a5)
    recv(buf)                -> kind of the next message (0: none), fields in buf
"""


# probe results (the HAL contract: every body answers probe() with one of these)
NOTHING = 0
OBJECT = 1   # a free (yellow) segment of the object
CLAIMED = 2  # a segment another robot holds (blue)
ROBOT = 3
WALL = 4
PROBE_NAMES = ("nothing", "object", "claimed", "robot", "wall")

# beacon(on) values
BEACON_OFF = 0
BEACON_ON = 1
BEACON_LEADER = 2

# codes of the HAL's queries and actions, as a recording captures them
# (SENSOR.query and ACTION.action, docs/protocol.md); index = code.
# recv_field is no query of its own: a recording's frames after a recv
# reading, one per 16-bit part of the frame the robot was handed
QUERY_NAMES = ("", "probe", "field_ahead", "field_here", "uphill", "holding", "recv", "x", "y",
               "recv_field")
ACTION_NAMES = ("", "forward", "claim", "carry", "beacon")
PROBE = 1
FIELD_AHEAD = 2
FIELD_HERE = 3
UPHILL = 4
HOLDING = 5
RECV = 6
POS_X = 7
POS_Y = 8
RECV_FIELD = 9
FORWARD = 1
CLAIM = 2
CARRY = 3
BEACON = 4


class Hal:
    """Base class documenting the interface; bodies override every method."""

    def x(self):
        raise NotImplementedError

    def y(self):
        raise NotImplementedError

    def probe(self, heading):
        raise NotImplementedError

    def field_ahead(self, heading):
        raise NotImplementedError

    def field_here(self):
        raise NotImplementedError

    def uphill(self):
        raise NotImplementedError

    def holding(self):
        raise NotImplementedError

    def forward(self, heading, step):
        raise NotImplementedError

    def claim(self, heading):
        raise NotImplementedError

    def carry(self, dx, dy):
        raise NotImplementedError

    def beacon(self, on):
        raise NotImplementedError

    def send(self, kind, a0, a1, a2, a3, a4, a5):
        raise NotImplementedError

    def recv(self, buf):
        raise NotImplementedError
