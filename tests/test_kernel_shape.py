"""The kernel's shape: the world's rules take the world state
(kernel.Grid, Robots, Run) and a run index, not dozens of positional
arguments, and every rule of the tick is written there once."""

import ast
import inspect

from sim_backend import body, engine, kernel
from sim_backend.batch import body as batch_body

MAX_PARAMS = 6


def _functions(module):
    tree = ast.parse(inspect.getsource(module))
    return [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)]


def test_every_kernel_function_takes_at_most_six_parameters():
    wide = {f.name: len(f.args.args) for f in _functions(kernel)
            if len(f.args.args) > MAX_PARAMS}
    assert not wide, f"kernel functions with more than {MAX_PARAMS} parameters: {wide}"


def test_the_bundles_name_each_field_once():
    for names in (kernel.GRID_FIELDS + kernel.TABLE_FIELDS + kernel.CELL_FIELDS,
                  kernel.ROBOT_FIELDS, kernel.RUN_FIELDS):
        assert len(set(names)) == len(names)


def test_the_turn_loops_and_fault_rules_live_in_the_kernel_only():
    """The engines call kernel.sync_tick / go_iteration and the fault rules;
    neither body nor engine draws an order, counts a turn's steps or draws a
    fault itself."""
    for module in (body, engine, batch_body):
        src = inspect.getsource(module)
        for word in ("faults.draw", "faults.RANDOM", "faults.IGNORE", "turn_steps",
                     "draw_order(", "apply_robot("):
            assert word not in src, (module.__name__, word)
