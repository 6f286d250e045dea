"""Faults injected on the body/world side, seeded and reproducible.

Which robots are faulty is planned once per run (`plan`) from a random stream
of its own (Python's `random.Random` seeded from the run seed and a fixed
salt), never from the robots' firmware RNG, so a run with every fault off is
bit-identical to a run without this module. The per-call draws of the sensor
faults come from `draw`, a pure integer hash of (run seed, robot, tick, call
number). The rules that apply them (start_turn, dead, stuck, sensed_probe,
sensed_field, ... in sim_backend/kernel.py) are written once, for the
reference engine and the batch engine (compiled by numba) alike, so both
engines see the same faults.

The robot's firmware never knows: a dead robot's actions, messages and
beacon go nowhere, a robot ignoring the field senses none, a random agent
senses neither field nor free segment (a segment looks like a robot in its
way), a probe may miss a segment or see one where none is.
"""

from __future__ import annotations

# no imports here: the batch engine transforms and compiles `draw`
# (sim_backend/batch/transform.py); the planning below is host side and
# imports what it needs where it runs

# per-robot flags (bits)
IGNORE_FIELD = 1     # non-complying: never senses the field
IGNORE_HOST = 2      # non-complying: drops the host's TRANSPORT and HALT
RANDOM = 4           # random agent: no field, never sees a free segment
NEVER = 1 << 40      # a tick no run reaches: "never dies / never stuck"

# draws are in per-ten-thousand (a scenario rate r is round(r * 10000))
SCALE = 10000
MASK31 = 0x7FFFFFFF
SALT = 0x5F17


def draw(seed, robot, tick, k):
    """A pseudo-random integer in 0..SCALE-1, a pure function of its
    arguments; every product stays below 2**62 (numba's int64 == Python's int)."""
    h = (seed * 1103515245 + SALT) & MASK31
    h = ((h ^ (robot * 2654435 + 12345)) * 1103515245 + 12345) & MASK31
    h = ((h ^ (tick * 40503 + 7)) * 1103515245 + 12345) & MASK31
    h = ((h ^ (k * 69069 + 1)) * 1103515245 + 12345) & MASK31
    h = (h ^ (h >> 13)) * 1103515245 & MASK31
    return (h >> 7) % SCALE


def active(sc) -> bool:
    """Does the scenario inject any fault?"""
    return any(getattr(sc, k) for k in RATE_KEYS) or sc.fieldNoise > 0


RATE_KEYS = ("deathRate", "deadlockRate", "ignoreFieldRate", "ignoreHostRate", "randomRate",
             "probeMiss", "probeGhost")


def plan(sc, seed: int) -> tuple[list[int], list[int], list[int], list[int]]:
    """Per robot (index 0 = node 1): death tick, stuck-from tick, stuck-until
    tick (NEVER when none) and fault flags. The shares of dead, non-complying
    (ignore field), non-complying (ignore host) and random robots are disjoint
    sets of round(rate * agents) robots each; a deadlock may strike any robot."""
    n = sc.agents
    die = [NEVER] * n
    s0 = [NEVER] * n
    s1 = [NEVER] * n
    flags = [0] * n
    if not active(sc):
        return die, s0, s1, flags
    import random
    rnd = random.Random(seed * 1_000_003 + SALT)
    order = list(range(n))
    rnd.shuffle(order)
    j = 0
    for rate, what in ((sc.deathRate, "die"), (sc.ignoreFieldRate, IGNORE_FIELD),
                       (sc.ignoreHostRate, IGNORE_HOST), (sc.randomRate, RANDOM)):
        for i in order[j:j + round(rate * n)]:
            if isinstance(what, int):
                flags[i] |= what
            else:                       # "die"
                die[i] = 1 + rnd.randrange(sc.faultWindow)
        j += round(rate * n)
    stuck = list(range(n))
    rnd.shuffle(stuck)
    for i in stuck[:round(sc.deadlockRate * n)]:
        s0[i] = 1 + rnd.randrange(sc.faultWindow)
        s1[i] = s0[i] + sc.deadlockTicks
    return die, s0, s1, flags


def feasible(sc, seed: int) -> bool:
    """Can the robots that never die and may claim still lift the object?"""
    die, _, _, flags = plan(sc, seed)
    able = sum(1 for d, f in zip(die, flags) if d == NEVER and not f & RANDOM)
    from sim_backend.scenario import holders_needed
    needed = holders_needed(sc, sc.weight_centi)
    return needed is None or able >= needed


def per_run(sc, seed: int) -> tuple[int, int, int, int]:
    """The run's sensor-fault figures: (hash seed, probe miss, probe ghost in
    per-ten-thousand, field noise amplitude)."""
    return (seed, round(sc.probeMiss * SCALE), round(sc.probeGhost * SCALE), sc.fieldNoise)
