"""main.py of a MicroPython robot (deployed by `touchswarm deploy`).

This file runs ON THE BOARD: plain MicroPython, no type hints, no f-strings.
It picks the board's serial port and starts the firmware's main loop
(firmware_logic/board.py). The robot's parameters come from `robot_config.py`
on the device when present (NODE, SEED, MODEL, SPAN, DEFIANCE, POWER,
MAX_TICKS, LINGER, HEAP_CHECK), else the defaults below. HEAP_CHECK = N runs
every tick after the first N under heap_lock() and counts the ticks that
tried to allocate (`main.LAST['guard'].faults`).

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


def config():
    c = {"NODE": 1, "SEED": 1, "MODEL": 1, "SPAN": 45, "DEFIANCE": 2, "POWER": 100,
         "MAX_TICKS": 0, "LINGER": 4, "HEAP_CHECK": 0,
         "BEHAVIOUR": "firmware_logic.behaviours.thesis"}
    try:
        import robot_config
        for k in c:
            if hasattr(robot_config, k):
                c[k] = getattr(robot_config, k)
    except ImportError:
        pass
    return c


LAST = {}    # the last run's HAL (counters, hal.robot), for inspection over the REPL


def main():
    from firmware_logic import board
    c = config()
    # the behaviour robot_config.py names (deploy --behaviour writes it)
    robot_mod = __import__(c["BEHAVIOUR"] + ".robot", None, None, ("Robot",))
    spec = __import__(c["BEHAVIOUR"] + ".spec", None, None, ("STATES",))
    guard = HeapGuard(c["HEAP_CHECK"]) if c["HEAP_CHECK"] else None
    LAST["guard"] = guard
    LAST["hal"] = board.run(StdioPort(), c["NODE"], c["SEED"], c["MODEL"], c["SPAN"], c["DEFIANCE"],
                     c["POWER"], c["MAX_TICKS"], c["LINGER"], robot_mod.Robot, spec, guard)
    return LAST["hal"]


if __name__ == "__main__":
    main()
