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


def test_quick_layout_is_the_full_walk():
    robots = _robots(6)
    quick, full = T.Layout(), _walked(robots)
    for r in robots:
        quick.add(r)
    assert list(quick.classes) == list(full.classes)
    for cls, cl in full.classes.items():
        q = quick.classes[cls]
        assert (q.name, q.fields) == (cl.name, cl.fields)
        assert [id(o) for o in q.instances] == [id(o) for o in cl.instances]
    assert quick.index == full.index


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
