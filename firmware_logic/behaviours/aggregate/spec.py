"""Aggregation with touch only, declared in one place.

Robots wander; a robot that touches another robot stops, lights its beacon
and reports where it stopped; a robot that senses a field climbs it, so
stopped robots seed clusters that grow. The host counts the robots that
stopped and halts the swarm once `quorum` percent of it has aggregated.
Same HAL and link messages as the thesis; a different FSM and coordinator.
"""

from firmware_logic.messages import UP

NAME = "aggregate"
TITLE = "Aggregation: touch a robot, stop, light the beacon; clusters grow uphill"

SEARCH = 0   # wandering, no field sensed
CLIMB = 1    # inside a field: uphill, then fieldDefiance random steps
STAY = 2     # touched a robot: stationary, beacon on, stop reported
HALT = 3     # halted by the host
STATES = ("search", "climb", "stay", "halt")

WALK = 1     # a random heading every step (the thesis's firefly)
TURN = 2     # turn within robotVisionSpan (the thesis's ant)
MODELS = ((WALK, "firefly"), (TURN, "ant"))

PARAMS = (
    ("movementModel", "firefly", None, None, "firefly (1) or ant (2)"),
    ("robotVisionSpan", 45, 0, 360, "ant turn range, degrees either side"),
    ("fieldDefiance", 2, 0, 50, "random steps between two uphill steps in a field"),
    ("quorum", 80, 1, 100, "percent of the swarm that must have stopped"),
)

# The behaviour's own message (messages.activate puts it beside the link's messages;
# the codec, the DBC, recordings and replay then know it like any other).
LEAVE = 7    # robot -> host: left its stop; the host drops it from its cluster at once
MESSAGES = (
    (LEAVE, "LEAVE", UP, "robot -> host: left the stop reported with seq, now at x, y",
     (("seq", 1, 0, 1, "", 1, None, ""),
      ("x", 2, 1, 256, "patch", None, None, ""),
      ("y", 2, 1, 256, "patch", None, None, ""))),
)

MEASURES = (
    ("found_tick", "tick the first robot stopped"),
    ("home_tick", "tick the quorum stopped (the host halts the swarm)"),
    ("stopped", "robots that stopped"),
    ("clusters", "groups of stopped robots touching each other (8-neighbours)"),
    ("largest", "robots in the largest cluster"),
)

# values the coordinator gives at every tick (coordinator.reporters(); one
# column each in `touchswarm run --trace`)
REPORTERS = (
    ("stopped", "robots that stopped"),
    ("clusters", "groups of stopped robots touching each other (8-neighbours)"),
    ("largest", "robots in the largest cluster"),
)
