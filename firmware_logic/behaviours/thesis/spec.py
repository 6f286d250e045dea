"""The thesis behaviour declared in one place: states, movement models,
its own messages, parameters and the measures a run reports.

Everything else derives from this module: the FSM's state constants
(robot.py imports them), the codec's validation, the DBC's value tables,
units and scaling, the scenario keys and their ranges, the CLI listings.
It is firmware subset (plain ints, strings and tuples) so a board can
import it; nothing here runs in the step path.
"""

NAME = "thesis"
TITLE = "Incremental perception (thesis Appendix A): search, touch, claim, field, transport"

# -- states (HEARTBEAT.state); the index is the code -------------------------
SEARCH = 0   # wandering, no field sensed (foundObject=false, foundField=false)
FIELD = 1    # inside a potential field: uphill, then fieldDefiance random steps
GRASP = 2    # claimed a segment; waiting for the grip to be confirmed
HOLD = 3     # holding the object: stationary, beacon on, touch reported
CARRY = 4    # centralised phase: moving with the object on the host's command
HALT = 5     # mission over or halted by the host
STATES = ("search", "field", "grasp", "hold", "carry", "halt")

# -- movement models (HELLO.model); the thesis's movementModel values --------
FIREFLY = 1
ANT = 2
MODELS = ((FIREFLY, "firefly"), (ANT, "ant"))

# -- this behaviour's messages (firmware_logic/messages.py has the common ones)
# kind code, name, direction ("up": robot -> host, "down": host -> robot),
# comment, fields; a field is (name, bytes, signed, divisor, unit, lo, hi)
# where the physical value is raw / divisor and lo..hi bounds the raw value
# beyond what its bytes allow (None: no further bound).
TRANSPORT = 2
TOUCH = 4
MESSAGES = (
    (TRANSPORT, "TRANSPORT", "down",
     "host -> carrier: transport step number and displacement in patches",
     (("step", 1, 0, 1, "", 1, None),
      ("dx", 1, 1, 1, "patch", -1, 1),
      ("dy", 1, 1, 1, "patch", -1, 1))),
    (TOUCH, "TOUCH", "up",
     "robot -> host: touch report, robot patch, touched segment, power",
     (("seq", 1, 0, 1, "", 1, None),
      ("rx", 1, 1, 1, "patch", None, None),
      ("ry", 1, 1, 1, "patch", None, None),
      ("sx", 1, 1, 1, "patch", None, None),
      ("sy", 1, 1, 1, "patch", None, None),
      ("power", 2, 0, 100, "power", 1, None))),
)

# -- parameters: thesis name, default, low, high, meaning ---------------------
# (scenario keys; the world's own keys are in sim_backend/scenario.py)
PARAMS = (
    ("movementModel", "firefly", None, None, "firefly (1) or ant (2)"),
    ("robotVisionSpan", 45, 0, 360, "ant turn range, degrees either side"),
    ("fieldDefiance", 2, 0, 50, "random steps between two uphill steps in a field"),
    ("rPower", "1.0", "0.01", "655.0", "power of one robot (weight units)"),
)

# -- measures a run reports (summary keys) -----------------------------------
MEASURES = (
    ("found_tick", "tick of the first touch"),
    ("converged_tick", "tick the holders' power reached the weight"),
    ("home_tick", "tick the object arrived home"),
    ("power", "power held at the end"),
    ("shape_iou", "IoU of the perceived shape with the true one"),
    ("leader", "node of the first finder"),
    ("delivered", "the object is home"),
)
