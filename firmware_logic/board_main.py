"""main.py of a MicroPython robot (deployed by `touchswarm deploy`).

This file runs ON THE BOARD: plain MicroPython, no type hints, no f-strings.
It picks the board's serial port, builds the behaviour's robot and starts the
firmware's main loop (firmware_logic/board.py). The behaviour is the package
`behaviour/` beside this file (deploy copies the behaviour's folder there, so
its relative imports work); `robot_config.py` (deploy writes it) gives:

    NODE        the robot's node id on the link
    ARGS        the FSM's constructor arguments, computed on the host by the
                behaviour's robot_args for this node, seed and scenario
    BEHAVIOUR   the behaviour's name (for people reading the board)
    MAX_TICKS, LINGER, HEAP_CHECK   the loop's (defaults below)

HEAP_CHECK = N runs every tick after the first N under heap_lock() and counts
the ticks that tried to allocate (`main.LAST['guard'].faults`).

On boards with USB serial (and on the unix port behind a pty) the link is
sys.stdin / sys.stdout in binary; nothing else may print on it.
"""

import sys
import time

try:
    import select
except ImportError:
    import uselect as select


class StdioPort:
    """The board's serial port as board.py wants it: read(timeout_ms) -> a
    byte or -1, write(buf, n), ms() -> time.ticks_ms() (the deadline
    of a request's answer). Allocation-free in steady state, so a whole
    board tick can run under micropython.heap_lock(): ipoll() reuses its
    result tuple (poll() builds a list), readinto() fills a preallocated
    byte (read(1) makes a bytes object), and the slices of the frame buffer
    are made once per buffer and length."""

    def __init__(self):
        self.inp = sys.stdin.buffer
        self.out = sys.stdout.buffer
        self.poller = select.poll()
        self.poller.register(sys.stdin, select.POLLIN)
        self.one = bytearray(1)
        self.views = None        # memoryview slices of the last buffer written, by length
        self.viewed = None
        # looked up once: a missing attribute raises, and raising allocates
        self.flush = getattr(self.out, "flush", None)
        self.ms = time.ticks_ms    # a small int below 2**30: no allocation

    def read(self, timeout_ms):
        for _ in self.poller.ipoll(timeout_ms):
            if self.inp.readinto(self.one) != 1:
                return -1
            return self.one[0]
        return -1

    def _view(self, buf):
        # its own method, and no comprehension: a comprehension would make
        # the buffer a closure cell, allocated on EVERY call of write()
        mv = memoryview(buf)
        views = []
        i = 0
        while i <= len(buf):
            views.append(mv[:i])
            i += 1
        self.views = views
        self.viewed = buf

    def write(self, buf, n):
        if buf is not self.viewed:
            self._view(buf)
        self.out.write(self.views[n])
        if self.flush is not None:
            self.flush()


HEAP_FAULT_FILE = "heap_fault.txt"


class HeapGuard:
    """HEAP_CHECK: every tick after the warm-up runs under heap_lock(); a
    tick that tries to allocate raises MemoryError and is counted (faults;
    first: its tick). board.run calls tick() instead of step + end_tick."""

    def __init__(self, warmup):
        import micropython
        self.warmup = warmup
        self.lock = micropython.heap_lock
        self.unlock = micropython.heap_unlock
        self.checked = 0
        self.faults = 0
        self.first = -1
        self.where = ""          # the first fault's traceback

    def tick(self, robot, hal):
        t = hal.tick
        fault = None
        self.lock()
        try:
            robot.step(hal)
            hal.end_tick()
        except MemoryError as err:
            fault = err
        finally:
            self.unlock()     # a counter: exactly one unlock per lock
        self.checked += 1
        if fault is not None:
            self.faults += 1
            if self.first < 0:
                self.first = t
                self.where = _traceback(fault)
                try:      # where a stalled board can still be read from
                    with open(HEAP_FAULT_FILE, "w") as f:
                        f.write("tick %d\n%s" % (t, self.where))
                except OSError:
                    pass


def _traceback(err):
    try:
        import io
    except ImportError:
        import uio as io
    buf = io.StringIO()
    sys.print_exception(err, buf)
    return buf.getvalue()


PACKAGE = "behaviour"      # the behaviour's folder on the board
LOOP = {"MAX_TICKS": 0, "LINGER": 4, "HEAP_CHECK": 0}


def config():
    """robot_config.py's keys, the loop's defaults beneath them."""
    import robot_config
    c = {}
    for k in LOOP:
        c[k] = LOOP[k]
    for k in ("NODE", "ARGS"):
        if not hasattr(robot_config, k):
            raise ValueError("robot_config.py lacks %s: deploy with `touchswarm deploy`" % k)
    for k in dir(robot_config):
        if k[:1] != "_":
            c[k] = getattr(robot_config, k)
    return c


def build(c):
    """(robot, spec): the behaviour's FSM (the class its __init__.py names in
    ROBOT, "module:Class") built from c["ARGS"], and its spec.py."""
    pkg = __import__(PACKAGE)
    parts = pkg.ROBOT.split(":")    # split: str.partition is optional in MicroPython
    modname, cls = parts[0], parts[1]
    mod = __import__(PACKAGE + "." + modname, None, None, (cls,))
    spec = __import__(PACKAGE + ".spec", None, None, ("STATES",))
    robot_class = getattr(mod, cls)
    return robot_class(*c["ARGS"]), spec


LAST = {}    # the last run's HAL (counters, hal.robot), for inspection over the REPL


def main():
    from firmware_logic import board
    c = config()
    robot, spec = build(c)
    guard = HeapGuard(c["HEAP_CHECK"]) if c["HEAP_CHECK"] else None
    LAST["guard"] = guard
    LAST["hal"] = board.run(StdioPort(), c["NODE"], robot, spec, c["MAX_TICKS"], c["LINGER"],
                            guard)
    return LAST["hal"]


if __name__ == "__main__":
    main()
