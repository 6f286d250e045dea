"""The coordinator contract as types (sim_backend/coordinator.py): every
installed behaviour's coordinator meets the host contract, its abilities are
read off the protocols, and a missing member is named."""

from __future__ import annotations

import pytest

from sim_backend import coordinator as C
from sim_backend import registry
from sim_backend.scenario import load


def make(behaviour: str):
    sc = load().replace(behaviour=behaviour)
    return registry.load(behaviour).coordinator(sc, journal=None, cells=None, on_reject=None)


@pytest.mark.parametrize("behaviour", sorted(registry.names()))
def test_every_installed_coordinator_meets_the_host_contract(behaviour: str) -> None:
    c = make(behaviour)
    assert C.lacks(c, C.HostCoordinator) == []
    assert isinstance(c, C.Coordinator) and isinstance(c, C.HostCoordinator)


def test_abilities_are_what_each_coordinator_declares() -> None:
    thesis, aggregate = make("thesis"), make("aggregate")
    assert isinstance(thesis, C.Tracking) and not isinstance(aggregate, C.Tracking)
    assert isinstance(aggregate, C.Measuring) and isinstance(aggregate, C.Segmenting)
    assert C.measures_of(aggregate) == aggregate.measures()
    assert isinstance(thesis, C.Recognising) and not isinstance(aggregate, C.Recognising)


def test_equip_gives_a_decider_only_to_a_coordinator_that_wants_one() -> None:
    from perception.decide import Decider, equip
    sc = load().replace(behaviour="thesis", recognise=True)
    wants = registry.load("thesis").coordinator(sc, journal=None, cells=None, on_reject=None)
    assert isinstance(equip(wants, sc).decider, Decider)
    plain, aggregate = make("thesis"), make("aggregate")
    assert equip(plain, sc).decider is None
    assert not hasattr(equip(aggregate, sc), "decider")


def test_a_coordinator_without_an_ability_is_named_what_it_lacks() -> None:
    class Bare:
        touches = ()
        delivered_tick = -1

        def on_message(self, node, kind, fields, tick):
            return None

        def tick(self, t):
            return []

        def status(self):
            return "bare"

    bare = Bare()
    assert isinstance(bare, C.Coordinator) and not isinstance(bare, C.Measuring)
    assert C.measures_of(bare) == {}
    assert C.lacks(bare, C.HostCoordinator) == ["nodes", "rejected", "replay", "snapshot",
                                                "adopt", "decision", "done", "carriers",
                                                "quiet"]


def test_has_asks_each_instance_for_the_data_members_its_class_lacks() -> None:
    # Recognising: a method the class carries, a data member set per instance
    class Maybe:
        def wants_decider(self):
            return True

    given, bare = Maybe(), Maybe()
    given.decider = None
    for _ in range(2):       # the second round answers from the class's cached members
        assert C.has(given, C.Recognising) and isinstance(given, C.Recognising)
        assert not C.has(bare, C.Recognising) and not isinstance(bare, C.Recognising)
    bare.decider = None
    assert C.has(bare, C.Recognising)


def test_has_lets_isinstance_decide_a_method_set_on_the_instance() -> None:
    class Later:
        decider = None

    c = Later()
    assert not C.has(c, C.Recognising)
    c.wants_decider = lambda: True
    assert C.has(c, C.Recognising) and isinstance(c, C.Recognising)
    c.wants_decider = None            # a protocol's method set to None is refused
    assert not C.has(c, C.Recognising) and not isinstance(c, C.Recognising)
