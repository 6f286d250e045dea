"""The thesis's behaviour (Appendix A): search, touch, claim, field, transport."""

# The wiring the registry reads (firmware_logic/registry.py); host side only.
ROBOT = "robot:Robot"
SUBSET_SETUP = ("robot_args", "make_coordinator")   # host side: may allocate


def robot_args(node, seed, sc):
    """The FSM's constructor arguments for robot `node` of scenario `sc`."""
    return (node, seed, sc.model, sc.robotVisionSpan, sc.fieldDefiance, sc.power_centi)


def make_coordinator(sc, journal=None):
    """The host coordinator of a mission in scenario `sc`."""
    from firmware_logic.behaviours.thesis.coordinator import Coordinator
    return Coordinator(sc.weight_centi, sc.homeX, sc.homeY, journal=journal)
