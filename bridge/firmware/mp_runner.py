"""Drive one scripted robot run; shared by CPython (imported) and MicroPython.

Under MicroPython (the unix port) it is run as a script:

    micropython mp_runner.py FWDIR trace TICKS
    micropython mp_runner.py FWDIR heap  WARMUP STEPS

FWDIR is put first on sys.path; it holds what a board holds (bridge/serial/
deploy.py): the package firmware_logic/ (compiled .mpy files, or .py
sources), the behaviour's package behaviour/, the board's main.py and a
robot_config.py with NODE, SEED and ARGS (the FSM's constructor arguments,
computed on the host by the behaviour's robot_args). The robot is built by
main.build, as on a board. `trace` prints one trace line per HAL call (see
firmware_logic/scripted.py) and an `end` line; `heap` prints one `heap ...`
line. Lines starting with '#' are diagnostics.

This file must stay valid MicroPython: no type hints, no f-strings, no
imports beyond sys, gc and micropython.
"""

import sys

TRACE_CAPACITY = 1024       # ints; one tick's records fit easily


def make_hal(spec, seed, horizon):
    """The scripted body of a run: it answers with the behaviour's STATES and
    sends the down messages its spec.MESSAGES declares."""
    from firmware_logic.scripted import ScriptHal

    return ScriptHal(seed, horizon, TRACE_CAPACITY, spec.STATES, getattr(spec, "MESSAGES", ()))


def run_trace(build, seed, ticks, emit):
    """Run `ticks` steps of the robot build() -> (robot, spec) makes,
    calling emit(line) for every trace line."""
    robot, spec = build()
    hal = make_hal(spec, seed, ticks)
    i = 0
    while i < ticks:
        robot.step(hal)
        hal.note_state(robot.state)
        for line in hal.drain_lines():
            emit(line)
        i += 1
    emit("end ticks %d actions %d records %d dropped %d" % (
        ticks, hal.actions, hal.records, hal.dropped))


def run_heap(build, seed, warmup, steps):
    """Heap bytes allocated over `steps` steps after `warmup` steps.

    Returns (allocated bytes, steps, bitmask of FSM states seen while
    measuring, index of the step that raised MemoryError under
    micropython.heap_lock() or -1).
    """
    import gc
    import micropython

    robot, spec = build()
    hal = make_hal(spec, seed, warmup + steps)
    i = 0
    while i < warmup:
        robot.step(hal)
        hal.note_state(robot.state)
        hal.clear()
        i += 1
    mask = 0
    gc.collect()
    gc.disable()
    a = gc.mem_alloc()
    i = 0
    while i < steps:
        robot.step(hal)
        hal.note_state(robot.state)
        hal.clear()
        mask |= 1 << robot.state
        i += 1
    b = gc.mem_alloc()
    gc.enable()

    # the same run again with the heap locked: any allocation raises
    robot, spec = build()
    hal = make_hal(spec, seed, warmup + steps)
    i = 0
    while i < warmup:
        robot.step(hal)
        hal.clear()
        i += 1
    failed = -1
    gc.collect()
    micropython.heap_lock()
    i = 0
    try:
        while i < steps:
            robot.step(hal)
            hal.clear()
            i += 1
    except MemoryError:
        failed = i
    micropython.heap_unlock()
    return b - a, steps, mask, failed


def main(argv):
    fwdir = argv[1]
    mode = argv[2]
    nums = []
    for a in argv[3:]:
        nums.append(int(a))
    sys.path.insert(0, fwdir)
    import main as board_main     # the board's main.py (firmware_logic/board_main.py)

    c = board_main.config()

    def build():
        return board_main.build(c)

    build()
    for name in sys.modules:
        if name.split(".")[0] == board_main.PACKAGE:
            print("# module " + name + " " + str(getattr(sys.modules[name], "__file__", "?")))
    if mode == "trace":
        run_trace(build, c["SEED"], nums[0], print)
    elif mode == "heap":
        r = run_heap(build, c["SEED"], nums[0], nums[1])
        print("heap %d %d %d %d" % r)
    else:
        print("# unknown mode " + mode)
        sys.exit(2)


if __name__ == "__main__":
    main(sys.argv)
