"""Drive one scripted robot run; shared by CPython (imported) and MicroPython.

Under MicroPython (the unix port) it is run as a script:

    micropython mp_runner.py FWDIR trace BEHAVIOUR NODE SEED MODEL SPAN DEFIANCE POWER TICKS
    micropython mp_runner.py FWDIR heap  BEHAVIOUR NODE SEED MODEL SPAN DEFIANCE POWER WARMUP STEPS

BEHAVIOUR is the behaviour package's module name (its robot.py holds Robot,
its spec.py the STATES), e.g. firmware_logic.behaviours.thesis.
FWDIR is put first on sys.path; it holds the package directory
firmware_logic/ (compiled .mpy files, or .py sources). `trace` prints one
trace line per HAL call (see firmware_logic/scripted.py) and an `end` line;
`heap` prints one `heap ...` line. Lines starting with '#' are diagnostics.

This file must stay valid MicroPython: no type hints, no f-strings, no
imports beyond sys, gc and micropython.
"""

import sys

TRACE_CAPACITY = 1024       # ints; one tick's records fit easily


BEHAVIOUR = "firmware_logic.behaviours.thesis"


def make(node, seed, model, span, defiance, power, horizon, behaviour=None):
    from firmware_logic.scripted import ScriptHal

    if behaviour is None:
        behaviour = BEHAVIOUR
    robot_mod = __import__(behaviour + ".robot", None, None, ("Robot",))
    spec = __import__(behaviour + ".spec", None, None, ("STATES",))
    robot = robot_mod.Robot(node, seed, model, span, defiance, power)
    hal = ScriptHal(seed, horizon, TRACE_CAPACITY, spec.STATES)
    return robot, hal


def run_trace(node, seed, model, span, defiance, power, ticks, emit, behaviour=None):
    """Run `ticks` steps, calling emit(line) for every trace line."""
    robot, hal = make(node, seed, model, span, defiance, power, ticks, behaviour)
    i = 0
    while i < ticks:
        robot.step(hal)
        hal.note_state(robot.state)
        for line in hal.drain_lines():
            emit(line)
        i += 1
    emit("end ticks %d actions %d records %d dropped %d" % (
        ticks, hal.actions, hal.records, hal.dropped))


def run_heap(node, seed, model, span, defiance, power, warmup, steps):
    """Heap bytes allocated over `steps` steps after `warmup` steps.

    Returns (allocated bytes, steps, bitmask of FSM states seen while
    measuring, index of the step that raised MemoryError under
    micropython.heap_lock() or -1).
    """
    import gc
    import micropython

    robot, hal = make(node, seed, model, span, defiance, power, warmup + steps)
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
    robot, hal = make(node, seed, model, span, defiance, power, warmup + steps)
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
    global BEHAVIOUR
    fwdir = argv[1]
    mode = argv[2]
    BEHAVIOUR = argv[3]
    nums = []
    for a in argv[4:]:
        nums.append(int(a))
    sys.path.insert(0, fwdir)
    robot_mod = __import__(BEHAVIOUR + ".robot", None, None, ("Robot",))

    print("# module " + str(getattr(robot_mod, "__file__", "?")))
    node, seed, model, span, defiance, power = nums[0], nums[1], nums[2], nums[3], nums[4], nums[5]
    if mode == "trace":
        run_trace(node, seed, model, span, defiance, power, nums[6], print)
    elif mode == "heap":
        r = run_heap(node, seed, model, span, defiance, power, nums[6], nums[7])
        print("heap %d %d %d %d" % r)
    else:
        print("# unknown mode " + mode)
        sys.exit(2)


if __name__ == "__main__":
    main(sys.argv)
