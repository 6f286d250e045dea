"""The int32 tables (sim_backend/batch/transform.py, TABLE): every int,
bool and object field of a class is a cell of one int32 table; a store the
transform proves to fit is a plain store, any other is checked when it runs
(borrow.fits), and a start value outside int32 is refused at the build: a
typed error either way, never a value wrapped round. Nothing here compiles
but the last test, which steps the thesis batch (the suite's shared step):
the rule is read off the layout and the generated text, and the check runs
as Python."""

import numpy as np
import pytest

from sim_backend.batch import borrow
from sim_backend.batch import transform as T
from sim_backend.errors import CompileError

DONE = 3


class _Toy:
    def __init__(self, param: int) -> None:
        self.param = param
        self.flag = False
        self.state = self.back = self.count = self.big = self.turn = self.pair = self.other = 0

    def step(self, x: int) -> None:
        self.state = DONE if x else 2      # module constant or literal: proved
        self.back = self.param             # a copy of a table cell: proved
        self.flag = x > 3                  # a comparison: proved
        self.count += 1                    # grows: checked
        self.big = x * 2                   # any value: checked
        self.turn = (self.turn + x) % 360  # a remainder by a literal: proved
        self.pair, self.other = 1, x       # one proved, one checked


def _poke(toys, k, v):
    toys[k].step(v)
    toys[k].state = toys[v].back       # another object's cell: proved


def _layout(params: list[int]) -> T.Layout:
    lay = T.Layout()
    lay.add_all([_Toy(p) for p in params])
    return lay


def _arrays(lay: T.Layout) -> dict:
    for cl in lay.classes.values():
        cl.finish()
    return T.state_arrays(lay)


def test_every_int_bool_and_object_field_is_a_cell_of_an_int32_table():
    lay = _layout([1, -2 ** 31, 2 ** 31 - 1])
    arrays = _arrays(lay)
    cl = lay.classes[_Toy]
    table = arrays[T.ints_name(cl)]
    assert table.dtype == np.int32
    assert table[:, cl.columns["param"]].tolist() == [1, -2 ** 31, 2 ** 31 - 1]


@pytest.mark.parametrize("value", [2 ** 31, -2 ** 31 - 1, 2 ** 62])
def test_a_start_value_outside_int32_is_refused_by_name(value):
    with pytest.raises(CompileError, match=rf"_Toy\.param = {value}: outside the int32"):
        _arrays(_layout([1, value]))


def test_a_store_not_proved_to_fit_is_checked_and_a_proved_one_is_not():
    lay = _layout([1, 2])
    text, _ = T.generate(lay, {"poke": (_poke, (T.ListOf(_Toy), T.SCALAR, T.SCALAR))})
    cl = lay.classes[_Toy]
    col = {a: f"_Toy__ints[self, {c}]" for a, c in cl.columns.items()}
    step = text[text.index("def F__Toy_step"):]
    step = step[:step.index("\n\n")]
    for line in (f"{col['state']} = 3 if x else 2",
                 f"{col['back']} = {col['param']}",
                 f"{col['flag']} = x > 3",
                 f"{col['count']} = fits({col['count']} + 1)",
                 f"{col['big']} = fits(x * 2)",
                 f"{col['turn']} = ({col['turn']} + x) % 360",
                 f"{col['pair']}, {col['other']} = (1, fits(x))"):
        assert f"    {line}\n" in step + "\n", line
    poke = text[text.index("__poke(_Toy__ints"):]           # its module's name is pytest's
    poke = poke[:poke.index("\n\n")]
    assert f"_Toy__ints[k, {cl.columns['state']}] = _Toy__ints[v, {cl.columns['back']}]" in poke
    assert "import NoAlias, borrow, clear, fits, prefetch" in text


def test_the_check_refuses_a_value_outside_int32_and_passes_the_rest():
    fits = borrow.fits.py_func
    for v in (T.TABLE_LO, -1, 0, 7, T.TABLE_HI):
        assert fits(v) == v
    for v in (T.TABLE_HI + 1, T.TABLE_LO - 1, 2 ** 62):
        with pytest.raises(OverflowError, match="outside int32"):
            fits(v)


def test_fields_come_back_from_the_int32_table():
    lay = _layout([4, 5])
    arrays = _arrays(lay)
    cl = lay.classes[_Toy]
    arrays[T.ints_name(cl)][1, cl.columns["state"]] = 2
    arrays[T.ints_name(cl)][1, cl.columns["flag"]] = 1
    arrays[T.ints_name(cl)][1, cl.columns["count"]] = 2 ** 31 - 1
    T.unpack(lay, arrays, cl.instances)
    toy = cl.instances[1]
    assert (toy.param, toy.state, toy.flag, toy.count) == (5, 2, True, 2 ** 31 - 1)
    assert type(toy.count) is int and cl.instances[0].flag is False


def test_a_stepped_value_past_int32_stops_the_batch_with_a_typed_one_line_error():
    # the thesis robot counts its ticks (`ticks += 1`, a checked store): one
    # robot's count set at the int32 edge overflows at the next tick, and the
    # batch refuses it by tick instead of wrapping it round
    from sim_backend.batch.soa import SoaEngine
    from sim_backend.errors import EngineError
    from sim_backend.scenario import validate
    eng = SoaEngine([(validate({"agents": 3, "objectWeight": 2}), 1)])
    eng.step()
    cl = next(c for c in eng.layout.classes.values() if "ticks" in c.columns)
    table = eng.arrays[T.ints_name(cl)]
    table[0, cl.columns["ticks"]] = 2 ** 31 - 1
    with pytest.raises(EngineError, match=r"^tick 2: a behaviour's field left") as e:
        eng.step()
    assert "\n" not in str(e.value)
