"""The thesis's behaviour (Appendix A): search, touch, claim, field, transport."""

# The wiring the registry reads (firmware_logic/registry.py); host side only.
ROBOT = "robot:Robot"
SUBSET_SETUP = ("robot_args", "make_coordinator")   # host side: may allocate


def robot_args(node, seed, sc):
    """The FSM's constructor arguments for robot `node` of scenario `sc`
    (its breed's keys when the scenario declares [[breeds]])."""
    if getattr(sc, "breeds", ()):
        sc = sc.for_node(node)
    return (node, seed, sc.model, sc.robotVisionSpan, sc.fieldDefiance, sc.power_centi,
            1 if sc.leaderField == "netlogo" else 0, 1 if sc.antBlocked == "turn" else 0,
            sc.levy_q, sc.mothNoise, sc.frogPause, sc.frogJump)


def make_coordinator(sc, journal=None, cells=None, on_reject=None):
    """The host coordinator of a mission in scenario `sc`.

    cells: the object's cells where it starts, when the host knows them (a
    simulation: `World(sc, seed).object_cells`); a TOUCH of any other cell is
    then rejected. Without them a touch need only be plausible (in the arena,
    next to the robot, not at home). journal, on_reject: the host contract
    (firmware_logic/roster.py).
    """
    from firmware_logic.behaviours.thesis.coordinator import Coordinator
    netlogo = sc.arrival == "netlogo"
    # the host's map: obstacles and the other objects, all placed at fixed
    # anchors (docs/scenarios.md); None in an open arena of one object
    closed = None
    recognise = getattr(sc, "recognise", False)
    if getattr(sc, "obstacles", ()) or len(getattr(sc, "objects", ())) > 1:
        closed = []
        # recognising, the map holds every object (the target too, until
        # the transport picks it); else the truth: the target is not in it
        first = 0 if recognise else 1
        for p in tuple(sc.obstacles) + tuple(sc.pieces()[first:]):
            if p.at is not None:     # a target placed at random is not on the map
                closed += p.placed(p.at[0], p.at[1])
    c = Coordinator(sc.weight_centi, sc.homeX, sc.homeY, journal=journal,
                    home_radius=1 if netlogo else 4, by_carrier=netlogo,
                    world_size=sc.worldSize, cells=None if recognise else cells,
                    on_reject=on_reject, blocked=closed,
                    lost_after=getattr(sc, "lostAfter", 0),
                    # a host that is not told the world's crowd rule (the
                    # host process) plans round lost holders, as under block
                    crowd_yields=getattr(sc, "crowd", "block") == "yield")
    if recognise:
        objects = None
        if closed is not None:
            objects = []
            for p in sc.pieces():
                if p.at is not None:
                    objects.append(frozenset(p.placed(p.at[0], p.at[1])))
        # the decider is host code (numpy): bridge.perception.host_coordinator gives it
        c.recognition(int(round(sc.confidence * 1000)), objects)
    return c
