"""The live view names only what a run has: the object when the scenario
places one, the host's estimate when a perception measure watches, home when
the behaviour has one (spec.HOME, by default when it declares LOAD). The
server says so in /info.json; the page's map legend follows it (headless
chromium, as tests/test_view.py drives it)."""

from __future__ import annotations

import pytest

from bridge.view.server import ViewServer
from bridge.view.sources import SimSource, home_of
from sim_backend import registry, scenario
from tests.test_view import browser, get, journal_server, text, wait_for  # noqa: F401,F811 - fixtures

SEED = 1
ALL_THREE = ("object", "host's estimate", "home (radius 2)")


def served(behaviour: str, **keys: object) -> ViewServer:
    sc = scenario.load("default").replace(behaviour=behaviour, **keys)
    return ViewServer(SimSource(sc, SEED), port=0).start()


@pytest.mark.parametrize("behaviour, keys, has", [
    ("thesis", {}, {"object": True, "estimate": True, "home": [-15, -15]}),
    ("aggregate", {}, {"object": True, "estimate": False, "home": None}),
    ("aggregate", {"object": "none"}, {"object": False, "estimate": False, "home": None}),
])
def test_info_says_what_the_run_has(behaviour, keys, has):
    server = served(behaviour, **keys)
    try:
        info = get(server, "/info.json")
    finally:
        server.stop()
    assert {k: info[k] for k in has} == has


def test_a_behaviour_declares_its_home_apart_from_its_load():
    agg = registry.load("aggregate")
    sc = scenario.load("default")
    assert home_of(sc, agg) is None
    agg.spec.HOME = True
    try:
        assert home_of(sc.replace(homeX=3, homeY=-4), agg) == [3, -4]
        agg.spec.HOME = "yes"
        with pytest.raises(registry.BehaviourError, match=r"spec.py HOME: 'yes' is not True or False"):
            home_of(sc, agg)
    finally:
        del agg.spec.HOME


def test_the_journal_names_no_object_nor_estimate(journal_server):  # noqa: F811
    info = get(journal_server[0], "/info.json")
    assert info["object"] is False and info["estimate"] is False
    assert info["home"] == [-15, -15]          # the journal's behaviour is the thesis


def legend(driver, server: ViewServer) -> str:
    driver.get(server.url)
    wait_for(driver, lambda d: "1 2 3: touches in order" in text(d, "map-legend"))
    return text(driver, "map-legend")


def test_the_legend_of_an_empty_aggregation_names_none_of_them(browser):  # noqa: F811
    server = served("aggregate", object="none")
    try:
        shown = legend(browser, server)
    finally:
        server.stop()
    for word in ALL_THREE + ("held cell",):
        assert word not in shown, shown


def test_the_legend_of_the_thesis_names_all_three(browser):  # noqa: F811
    server = served("thesis")
    try:
        shown = legend(browser, server)
    finally:
        server.stop()
    for word in ALL_THREE:
        assert word in shown, shown
