"""The thesis's behaviour (Appendix A): search, touch, claim, field, transport."""

# The wiring the registry reads (sim_backend/registry.py); host side only.
ROBOT = "robot:Robot"
# host libraries that equip its coordinator, as "module:function(coordinator,
# scenario)": the recogniser's decider (numpy; scenario recognise = true)
HOST_EQUIP = ("perception.decide:equip",)
SUBSET_SETUP = ("robot_args", "_scenario_args", "make_coordinator", "holders_needed",
                "summary_values", "_weight_text")  # host side: may allocate


# Under NetLogo's sequential activation a robot in this state takes 1 + the
# parameter's value FSM steps per go iteration (go: FollowField, then
# `repeat fieldDefiance [RandomHead]`); the world reads it (sim_backend/world.py).
MULTI_STEP = ("field", "fieldDefiance")


def model_code(name):
    """The FSM's code of movement model `name` (spec.MODELS)."""
    from .spec import MODELS
    for code, known in MODELS:
        if known == name:
            return code
    raise ValueError("movementModel: %r is not one of this behaviour's models" % (name,))


def power_centi(sc):
    """One robot's power in hundredths (HELLO.power)."""
    return round(sc.rPower * 100)


def robot_args(node, seed, sc):
    """The FSM's constructor arguments for robot `node` of scenario `sc`
    (sc is already the robot's breed's scenario when [[breeds]] are declared)."""
    last = _LAST[0]
    if last is None or last[0] is not sc:
        last = (sc, _scenario_args(sc))
        # one store: threads building batches at once each see a whole pair
        _LAST[0] = last
    return (node, seed) + last[1]


# (scenario, its part of robot_args) of the last scenario asked: a batch
# builds all of a run's robots (tens of thousands per sweep worker) from one
# scenario object, and read its parameters per robot. Held by identity (a
# scenario is frozen, and the pair keeps it alive, so no other can take its
# id); a breed's robots each get a scenario of their own and miss it.
_LAST = [None]


def _scenario_args(sc):
    """robot_args's arguments after node and seed: the scenario's alone."""
    model = model_code(sc.movementModel)
    # per mille chance a Levy flight doubles (robot.py _new_flight): 2**(1 - mu)
    levy_q = round(1000 * 2 ** (1 - sc.levyMu))
    return (model, sc.robotVisionSpan, sc.fieldDefiance, power_centi(sc),
            1 if sc.leaderField == "netlogo" else 0, 1 if sc.antBlocked == "turn" else 0,
            levy_q, sc.mothNoise, sc.frogPause, sc.frogJump,
            1 if sc.firstMove == "netlogo" else 0)


def holders_needed(sc, weight_centi):
    """The fewest robots whose power together reaches the weight (the
    scenario's checks; more than the swarm when it cannot)."""
    if not sc.breeds:
        return -(-weight_centi // power_centi(sc))
    powers = []
    for n in range(1, sc.agents + 1):
        powers.append(power_centi(sc.for_node(n)))
    powers.sort(reverse=True)
    total = 0
    for k, p in enumerate(powers, 1):
        total += p
        if total >= weight_centi:
            return k
    return sc.agents + 1


def check(sc):
    """The thesis's own rules over a whole scenario; ValueError names the key."""
    from .robot import HEARTBEAT_EVERY
    if 0 < sc.lostAfter <= HEARTBEAT_EVERY:
        # a holder waiting for the transport reports once per HEARTBEAT_EVERY
        raise ValueError("lostAfter: %d must be 0 (never) or more than %d, the ticks "
                         "between a waiting holder's reports" % (sc.lostAfter, HEARTBEAT_EVERY))
    if sc.recognise and sc.lostAfter:
        # both change which holders' power counts; their interplay is not built
        raise ValueError("recognise: not built together with lostAfter; set one of them")


def _weight_text(centi):
    """Hundredths as weight units, the way %g prints them: 5, 2.5, 0.16."""
    whole, frac = centi // 100, centi % 100
    if frac == 0:
        return "%d" % whole
    if frac % 10 == 0:
        return "%d.%d" % (whole, frac // 10)
    return "%d.%02d" % (whole, frac)


def summary_values(coord):
    """The text summary's own values (spec.SUMMARY `held`): the power held
    when the holders first matched the weight; the summary's power is the
    final one, which later touches may have raised."""
    if coord.converged_tick < 0:
        return {"held": "(power %s held at the end)" % _weight_text(coord.power)}
    held = 0
    for t in coord.touches:
        if t.tick <= coord.converged_tick:
            held += t.power
    return {"held": "(power %s held then)" % _weight_text(held)}


def make_coordinator(sc, journal=None, cells=None, on_reject=None):
    """The host coordinator of a mission in scenario `sc`.

    cells: the object's cells where it starts, when the host knows them (a
    simulation: `World(sc, seed).object_cells`); a TOUCH of any other cell is
    then rejected. Without them a touch need only be plausible (in the arena,
    next to the robot, not at home). journal, on_reject: the host contract
    (firmware_logic/roster.py).
    """
    from .coordinator import Coordinator
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
        # the decider is host code (numpy): perception.host_coordinator gives it
        c.recognition(int(round(sc.confidence * 1000)), objects)
    return c
