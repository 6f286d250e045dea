"""The thesis behaviour declared in one place: states, movement models,
its own messages, parameters and the measures a run reports.

Everything else derives from this module: the FSM's state constants
(robot.py imports them), the codec's validation, the DBC's value tables,
units and scaling, the scenario keys and their ranges, the CLI listings.
It is firmware subset (plain ints, strings and tuples) so a board can
import it; nothing here runs in the step path.
"""

from firmware_logic.messages import DOWN

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
LEVY = 3     # Levy walk: straight flights of power-law length (docs/movement-models.md)
MOTH = 4     # moth-like: steers up the field with noise, circles where it peaks
FROG = 5     # frog-like: pauses looking round, then jumps several patches
MODELS = ((FIREFLY, "firefly"), (ANT, "ant"), (LEVY, "levy"), (MOTH, "moth"), (FROG, "frog"))

# -- messages: the link's own (firmware_logic/messages.py MESSAGES); this
# behaviour fills HELLO.model with MODELS and HEARTBEAT.state with STATES.
# The thesis's TOUCH and TRANSPORT kinds are link messages too, since the
# host process understands them. Its own (messages.activate puts them in use; the
# codec, the DBC, recordings, replay and the journal derive from this row):
# A command is at most 4 bytes, so a SecOC-sealed frame (bridge/links/secoc.py)
# keeps room for its MAC and freshness.
RELEASE = 8  # host -> holder: a decoy (scenario recognise = true), or a refused touch
RELEASE_TICKS = 300   # ticks a released robot claims nothing in the RELEASE box
MESSAGES = (
    (RELEASE, "RELEASE", DOWN,
     "host -> holder: the object is not the target; let go, search on and claim no "
     "segment in x0..x1, y0..y1 for RELEASE_TICKS (300) ticks",
     (("x0", 1, 1, 1, "patch", None, None, ""),
      ("y0", 1, 1, 1, "patch", None, None, ""),
      ("x1", 1, 1, 1, "patch", None, None, ""),
      ("y1", 1, 1, 1, "patch", None, None, ""))),
)

# -- parameters: thesis name, default, low, high, meaning ---------------------
# Scenario keys of scenarios running this behaviour (the world's own keys are
# in sim_backend/scenario.py). The kind is read off the row (sim_backend/params.py):
# an int default is an int in low..high; True/False a bool; text with text
# bounds a float ("1.0"); text with a tuple of words in `low` one of them;
# text with no bounds one of MODELS.
PARAMS = (
    ("movementModel", "firefly", None, None,
     "firefly (1), ant (2), levy (3), moth (4) or frog (5)"),
    ("robotVisionSpan", 45, 0, 360, "ant turn range, degrees either side"),
    ("fieldDefiance", 2, 0, 50, "random steps between two uphill steps in a field"),
    ("rPower", "1.0", "0.01", "655.0", "power of one robot (weight units)"),
    ("antBlocked", "random", ("random", "turn"), None,
     "an ant blocked on its step: random heading (thesis) or turn within its span"),
    ("levyMu", "2.0", "1.1", "3.0", "Levy walk: power-law exponent of flight lengths"),
    ("mothNoise", 30, 0, 180, "moth: noise on its uphill heading, degrees either side"),
    ("frogPause", 4, 1, 100, "frog: ticks it sits looking round between jumps"),
    ("frogJump", 4, 1, 30, "frog: patches of one jump"),
    # the host's side (coordinator.py)
    ("lostAfter", 0, 0, 1000000, "host: a holder silent this many ticks is lost (0: never)"),
    ("recognise", False, None, None,
     "host: recognise the target from the touches (no truth), release holders of decoys"),
    ("confidence", "0.9", "0.5", "0.999",
     "recognise: the posterior needed to call a cluster the target (or not)"),
)

# -- measures a run reports (summary keys) -----------------------------------
MEASURES = (
    ("found_tick", "tick of the first touch"),
    ("converged_tick", "tick the holders' power reached the weight"),
    ("home_tick", "tick the object arrived home"),
    ("power", "power held at the end"),
    ("shape_iou", "IoU of the perceived shape with the true one"),
    # the thesis's own shape (DrawShape, Figures 22-24): the polygon through
    # the holders' rounded positions; the cells it encloses against the object
    ("polygon_iou", "IoU with the true shape of the cells the holders' polygon encloses"),
    ("leader", "node of the first finder"),
    ("segments", "the touched segments, in touch order (object cells relative to its centre)"),
    ("converged_moves", "robot moves to convergence (under netlogo more than one per tick)"),
    ("delivered", "the object is home"),
    ("outcome", "delivered, no path home, stalled, transporting or collecting touches"),
    ("target_tick", "recognise: tick a cluster of touches was first recognised as the target"),
    ("target_permille", "recognise: the posterior it had then, per mille"),
    ("releases", "recognise: RELEASE commands sent to holders of decoys"),
    ("wrong_transport", "recognise: the transport began on an object that is not the target"),
)

# -- reporters: values the coordinator gives at every tick (the per-tick trace,
# `touchswarm run --trace`, has one column each; coordinator.reporters()) -----
REPORTERS = (
    ("holders", "robots holding the object (accepted touches)"),
    ("home_d2", "squared patch distance from the object's nearest segment to home, -1 before a touch"),
)

# -- words: how the outputs speak of a run (sim_backend/words.py reads these;
# optional: a behaviour without them gets one summary line and one sweep-plot
# panel per measure, titled by its meaning, and no power bar or shape panel)
HEADER = "scenario {scenario}: {robots} {movementModel} robots, object {object}, seed {seed}"
SUMMARY = (
    ("first touch", "{found_tick!t}"),
    ("converged", "{converged_tick!t}  {held}"),   # held: __init__.summary_values
    ("delivered home", "{home_tick!t}"),
    ("leader", "robot {leader}"),
    ("touches", "{touches!n} robots hold the object, power {power:g}"),
    ("shape IoU", "{shape_iou:.3f}"),
    ("polygon IoU", "{polygon_iou:.3f}"),
)
RESULT = ("delivered", "DELIVERED", "NOT delivered")
SHAPE = "shape_iou"          # world.png's perceived-vs-true panel, perceived cells drawn
LOAD = ("power", "weight")   # the live view's bar: the holders' power of the weight
PLOTS = (
    ("converged_tick", "convergence tick"),
    ("delivered", "delivery rate"),
    ("shape_iou", "shape IoU"),
    ("polygon_iou", "holder polygon IoU"),
)
