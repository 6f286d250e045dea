"""Deterministic random numbers that stay inside MicroPython's small ints.

Two multiply-with-carry lanes with base 2**15. Each lane's state stays below
a * 2**15 < 2**30, so no step allocates on a 32-bit board, and the same
integer maths gives bit-identical streams on CPython, MicroPython and numpy.
The multipliers make a*2**15 - 1 a safe prime, giving each lane a period
near 2**29; the two periods are coprime, so the pair repeats after ~2**58.
"""

A1 = 32760
A2 = 32730
MASK15 = 0x7FFF
M1 = A1 * 32768 - 1
M2 = A2 * 32768 - 1
SUBSET_SETUP = ("seed_state",)   # start-up only; returns a tuple


def seed_state(seed, node):
    """Initial lane states for robot `node` of a run seeded with `seed`.

    Runs once at start-up; may use big ints on a board, never in the step path.
    """
    s = (seed % 1000003) * 7919 + (node % 65521) * 104729 + 12345
    x = s % (M1 - 1) + 1
    y = (s * 31 + 977) % (M2 - 1) + 1
    return x, y


class Rng:
    def __init__(self, seed, node):
        x, y = seed_state(seed, node)
        self.x = x
        self.y = y
        # Discard the first outputs: nearby seeds start on nearby states.
        i = 0
        while i < 8:
            self.next30()
            i += 1

    def next30(self):
        x = A1 * (self.x & MASK15) + (self.x >> 15)
        y = A2 * (self.y & MASK15) + (self.y >> 15)
        self.x = x
        self.y = y
        return ((x & MASK15) << 15) | (y & MASK15)

    def below(self, n):
        """Uniform-ish integer in [0, n); NetLogo's `random n` (0 when n <= 0)."""
        if n <= 0:
            return 0
        return self.next30() % n
