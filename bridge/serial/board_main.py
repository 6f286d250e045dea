"""main.py of a MicroPython robot (deployed by `touchswarm deploy`).

This file runs ON THE BOARD: plain MicroPython, no type hints, no f-strings.
It picks the board's serial port and starts the firmware's main loop
(firmware_logic/board.py). The robot's parameters come from `robot_config.py`
on the device when present (NODE, SEED, MODEL, SPAN, DEFIANCE, POWER,
MAX_TICKS, LINGER), else the defaults below.

On boards with USB serial (and on the unix port behind a pty) the link is
sys.stdin / sys.stdout in binary; nothing else may print on it.
"""

import sys

try:
    import select
except ImportError:
    import uselect as select


class StdioPort:
    def __init__(self):
        self.inp = sys.stdin.buffer
        self.out = sys.stdout.buffer
        self.poller = select.poll()
        self.poller.register(sys.stdin, select.POLLIN)

    def read(self, timeout_ms):
        if not self.poller.poll(timeout_ms):
            return -1
        b = self.inp.read(1)
        if not b:
            return -1
        return b[0]

    def write(self, buf, n):
        self.out.write(memoryview(buf)[:n])
        try:
            self.out.flush()
        except AttributeError:
            pass


def config():
    c = {"NODE": 1, "SEED": 1, "MODEL": 1, "SPAN": 45, "DEFIANCE": 2, "POWER": 100,
         "MAX_TICKS": 0, "LINGER": 4, "BEHAVIOUR": "firmware_logic.behaviours.thesis"}
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
    LAST["hal"] = board.run(StdioPort(), c["NODE"], c["SEED"], c["MODEL"], c["SPAN"], c["DEFIANCE"],
                     c["POWER"], c["MAX_TICKS"], c["LINGER"], robot_mod.Robot, spec)
    return LAST["hal"]


if __name__ == "__main__":
    main()
