"""Aggregation: the second behaviour, exercising the seam end to end."""

# The wiring the registry reads (sim_backend/registry.py); host side only.
ROBOT = "robot:Robot"
SUBSET_SETUP = ("robot_args", "make_coordinator")   # host side: may allocate


def robot_args(node, seed, sc):
    """The FSM's constructor arguments for robot `node` of scenario `sc`."""
    from .spec import MODELS
    model = 0
    for code, name in MODELS:
        if name == sc.movementModel:
            model = code
    # HELLO's power: every robot alike (aggregation lifts nothing)
    return (node, seed, model, sc.robotVisionSpan, sc.fieldDefiance, 100)


def make_coordinator(sc, journal=None, cells=None, on_reject=None):
    """The host coordinator: halt once `quorum` percent of the swarm stopped.

    cells (the object's cells) is accepted like the thesis's and unused:
    aggregation has no object. journal, on_reject: the host contract
    (firmware_logic/roster.py)."""
    from .coordinator import Coordinator
    return Coordinator(sc.agents, sc.quorum, journal=journal,
                       on_reject=on_reject, world_size=getattr(sc, "worldSize", None))
