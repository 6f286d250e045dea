"""A batch's build: the layout's quick path for instances that look like
one already walked gives the full walk's layout, and refuses what it refuses."""

import pytest

from sim_backend import registry
from sim_backend.batch import transform as T
from sim_backend.errors import CompileError
from sim_backend.scenario import Scenario


def _robots(n: int) -> list:
    sc = Scenario(agents=n)
    beh = registry.load(sc.behaviour)
    return [beh.make_robot(node, seed, sc) for seed in (1, 2) for node in range(1, n + 1)]


def _walked(objs: list) -> T.Layout:
    """The layout every instance's full walk gives."""
    lay = T.Layout()
    for o in objs:
        lay._add(o, type(o))
    return lay


def _same_layout(a: T.Layout, b: T.Layout) -> None:
    assert list(a.classes) == list(b.classes)
    for cls, cl in b.classes.items():
        q = a.classes[cls]
        assert (q.name, q.fields) == (cl.name, cl.fields)
        assert [id(o) for o in q.instances] == [id(o) for o in cl.instances]
    assert a.index == b.index


def test_quick_layout_is_the_full_walk():
    robots = _robots(6)
    quick, full = T.Layout(), _walked(robots)
    for r in robots:
        quick.add(r)
    _same_layout(quick, full)


def test_quick_layout_still_refuses_a_field_of_another_type():
    robots = _robots(3)
    robots[2].heading = True         # a bool where the others hold an int
    lay = T.Layout()
    with pytest.raises(CompileError, match="heading"):
        for r in robots:
            lay.add(r)


def test_quick_layout_still_refuses_a_missing_field():
    robots = _robots(3)
    del robots[1].rxbuf
    lay = T.Layout()
    with pytest.raises(CompileError, match="rxbuf"):
        for r in robots:
            lay.add(r)


def test_scenario_parameter_read_by_name():
    sc = Scenario()
    for name, value in sc.params:
        assert getattr(sc, name) == value
    with pytest.raises(AttributeError, match="no key"):
        sc.noSuchKey
    assert sc.replace(**{sc.params[0][0]: sc.params[0][1]}) == sc


def test_layout_values_are_every_field_of_every_instance():
    robots = _robots(4)
    lay = T.Layout()
    for r in robots:
        lay.add(r)
    for cl in lay.classes.values():
        got = lay.values(cl)
        assert list(got) == list(cl.fields)
        for attr in cl.fields:
            assert list(got[attr]) == [getattr(o, attr) for o in cl.instances]


def _one_by_one(objs: list) -> T.Layout:
    lay = T.Layout()
    for o in objs:
        lay.add(o)
    return lay


def _arrays(lay: T.Layout) -> dict:
    for cl in lay.classes.values():
        cl.finish()                        # as a build's T.shape does
    return T.state_arrays(lay)


def _shared_rng(robots: list) -> list:
    robots[3].rng = robots[1].rng          # one instance held by two robots
    return robots


def _repeated(robots: list) -> list:
    return robots + robots[2:4]            # the same robots listed again


def _rng_as_robot(robots: list) -> list:
    return robots[:3] + [robots[0].rng] + robots[3:]     # another class between


@pytest.mark.parametrize("change", [lambda r: r, _shared_rng, _repeated, _rng_as_robot])
def test_a_batchs_robots_laid_out_at_once_as_one_by_one(change):
    robots = change(_robots(5))
    bulk = T.Layout()
    bulk.add_all(robots)
    _same_layout(bulk, _one_by_one(robots))
    got, want = _arrays(bulk), _arrays(_one_by_one(robots))
    assert list(got) == list(want)
    for name, v in want.items():
        assert getattr(got[name], "tolist", lambda: got[name])() == \
            getattr(v, "tolist", lambda: v)()


def _bool_heading(robots: list) -> None:
    robots[7].heading = True


def _short_rxbuf(robots: list) -> None:
    robots[7].rxbuf = robots[7].rxbuf[1:]


def _float_in_rxbuf(robots: list) -> None:
    robots[7].rxbuf[2] = 0.5


def _no_rxbuf(robots: list) -> None:
    del robots[7].rxbuf


def _bool_in_rng(robots: list) -> None:
    robots[7].rng.x = False


@pytest.mark.parametrize("change, field", [(_bool_heading, "heading"), (_short_rxbuf, "rxbuf"),
                                           (_float_in_rxbuf, "rxbuf"), (_no_rxbuf, "rxbuf"),
                                           (_bool_in_rng, r"\.x")])
def test_a_batch_laid_out_at_once_refuses_what_one_by_one_refuses(change, field):
    robots = _robots(5)
    change(robots)
    for lay in (T.Layout(), None):
        with pytest.raises(CompileError, match=field):
            if lay is None:
                _one_by_one(robots)
            else:
                lay.add_all(robots)


def test_state_arrays_table_holds_every_int_and_bool_field_of_every_instance():
    robots = _robots(4)
    robots[5].heading = 2 ** 31 - 1      # the int32 table's edge (transform.TABLE)
    robots[6].heading = -2 ** 31
    lay = T.Layout()
    lay.add_all(robots)
    arrays = _arrays(lay)
    for cl in lay.classes.values():
        table = arrays[T.ints_name(cl)].tolist()
        for attr, f in cl.fields.items():
            if f[0] in ("int", "bool"):
                assert [row[cl.columns[attr]] for row in table] == \
                    [int(getattr(o, attr)) for o in cl.instances]
            elif f[0] == "inst":
                assert [row[cl.columns[attr]] for row in table] == \
                    [lay.index[id(getattr(o, attr))][1] for o in cl.instances]


def test_state_arrays_refuse_a_value_past_the_int32_table_by_name():
    robots = _robots(4)
    robots[5].heading = 2 ** 62          # a board's int holds 31 bits; no wrapping here
    lay = T.Layout()
    lay.add_all(robots)
    with pytest.raises(CompileError, match=r"Robot\.heading = 4611686018427387904: outside"):
        _arrays(lay)
