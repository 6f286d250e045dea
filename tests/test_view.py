"""`touchswarm view`: the JSON and control endpoints, the page in headless
chromium (Debian's, through selenium; `make chromium` installs it), the host
journal as a source, and the command's one-line errors.

Nothing here waits on time: the simulated run is stepped through the control
endpoint, and the browser is waited on with WebDriverWait on a DOM condition
(the timeout is only a hang guard).
"""

from __future__ import annotations

import json
from pathlib import Path
import socket
import sqlite3
import urllib.error
import urllib.request

import pytest

from bridge.cli import main
from bridge.host.journal import Journal
from bridge.host.process import LIVE_EVERY, HostProcess
from bridge.view.server import ViewServer
from bridge.view.sources import JournalSource, SimSource
from firmware_logic import messages as msg
from sim_backend import scenario
from tests.test_journal import FakeTransport

HANG_GUARD = 120.0       # seconds; a hang guard only, never a measurement
SEED = 1


def get(server: ViewServer, path: str) -> dict:
    with urllib.request.urlopen(server.url + path.lstrip("/"), timeout=HANG_GUARD) as r:
        return json.loads(r.read())


def post(server: ViewServer, path: str, body: bytes | dict | None = None) -> tuple[int, dict]:
    data = body if isinstance(body, bytes) else json.dumps(body or {}).encode()
    req = urllib.request.Request(server.url + path.lstrip("/"), data=data, method="POST",
                                 headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(req, timeout=HANG_GUARD) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as err:
        return err.code, json.loads(err.read())


@pytest.fixture
def sim():
    server = ViewServer(SimSource(scenario.load("default"), SEED), port=0).start()
    yield server
    server.stop()


def write_hello(j: Journal, node: int) -> None:
    j.add_report(node, msg.HELLO, (1, 100, 1), 0)       # firefly, power 1.00, version 1


@pytest.fixture
def journal_server(tmp_path):
    path = tmp_path / "host.db"
    with Journal(path) as j:
        j.bind("thesis")
        write_hello(j, 3)
    server = ViewServer(JournalSource(path, scenario.load("default")), port=0).start()
    yield server, path
    server.stop()


# -- (1) endpoints, no browser -----------------------------------------------


def test_info_and_state_describe_the_run(sim):
    info = get(sim, "/info.json")
    assert info["source"] == "sim" and info["controls"] is True
    assert info["world"] == 18 and info["home"] == [-15, -15]
    assert len(info["colours"]) == len(info["states"]) and "hold" in info["states"]
    st = get(sim, "/state.json")
    assert st["tick"] == 0 and st["playing"] is False and st["touches"] == []
    assert len(st["robots"]) == 20 and st["object"]
    assert st["field"]["n"] == 37 and len(st["field"]["cells"]) == 37 * 37
    assert st["weight"] == 5.0 and st["power"] == 0.0


def test_step_advances_exactly_the_ticks_asked(sim):
    code, s = post(sim, "/control/step")
    assert (code, s["tick"]) == (200, 1)
    code, s = post(sim, "/control/step", {"ticks": 1})
    assert s["tick"] == 2
    code, s = post(sim, "/control/step", {"ticks": 5})
    assert s["tick"] == 7 and s["playing"] is False
    assert get(sim, "/state.json")["tick"] == 7


def test_play_runs_and_pause_stops_it(sim):
    code, s = post(sim, "/control/speed", {"ticks_per_second": 1000})
    assert code == 200 and s["speed"] == 1000
    code, s = post(sim, "/control/play")
    assert code == 200 and s["playing"] is True
    st = get(sim, "/state.json")
    for _ in range(100000):               # the runner steps it: wait for the first tick
        if st["tick"] > 0:
            break
        st = get(sim, "/state.json")
    assert st["tick"] > 0
    code, paused = post(sim, "/control/pause")
    assert code == 200 and paused["playing"] is False
    # paused: nothing moves it but a step, which moves it by exactly one
    code, s = post(sim, "/control/step")
    assert s["tick"] == paused["tick"] + 1
    assert get(sim, "/state.json")["tick"] == paused["tick"] + 1


@pytest.mark.parametrize("path, body, words", [
    ("/control/step", {"ticks": 0}, "ticks must be an integer"),
    ("/control/step", {"ticks": "two"}, "ticks must be an integer"),
    ("/control/speed", {"ticks_per_second": -3}, "ticks_per_second must be a number"),
    ("/control/speed", {}, "ticks_per_second must be a number"),
    ("/control/rewind", {}, "unknown control 'rewind'"),
    ("/control/step", b"{not json", "not JSON"),
    ("/control/step", b"[1, 2]", "a JSON object"),
])
def test_a_bad_request_gets_400_and_one_line(sim, path, body, words):
    code, s = post(sim, path, body)
    assert code == 400
    assert words in s["error"] and "\n" not in s["error"]
    assert get(sim, "/state.json")["tick"] == 0        # and nothing happened


def test_journal_source_has_no_controls(journal_server):
    server, _ = journal_server
    assert get(server, "/info.json")["controls"] is False
    code, s = post(server, "/control/step")
    assert code == 400 and "journal source follows a host" in s["error"]


def test_journal_source_shows_touches_and_poses(journal_server):
    server, path = journal_server
    assert get(server, "/state.json")["touches"] == []
    with Journal(path) as j:
        j.add_report(3, msg.TOUCH, (1, 2, 3, 3, 3, 100), 17)
        j.set_live({"tick": 20, "poses": {"3": [19, 3, 2 * 256, 3 * 256 + 128, 90, 0]},
                    "bad_frames": {"crc": 2}, "messages": 9})
    st = get(server, "/state.json")
    assert [(t["n"], t["node"], t["sx"], t["sy"]) for t in st["touches"]] == [(1, 3, 3, 3)]
    assert st["power"] == 1.0 and st["perceived"] == [[3, 3]] and st["tick"] == 20
    assert st["robots"] == [{"node": 3, "x": 2.0, "y": 3.5, "state": 3, "heard_tick": 19}]
    assert st["bad_frames"] == {"crc": 2}
    assert any("TOUCH from robot 3" in e for e in st["events"])


def test_host_journals_poses_and_bad_frames(tmp_path):
    tr = FakeTransport()
    with Journal(tmp_path / "j.sqlite") as j:
        h = HostProcess(tr, weight=500, journal=j)
        h.handle([(4, msg.HELLO, (1, 100, 1)), (4, msg.HEARTBEAT, (0, 512, -256, 45, 0)),
                  (9, msg.HEARTBEAT, (0, 0, 0, 0, 0))])      # 9 never said HELLO: a bad frame
        for _ in range(LIVE_EVERY - 1):
            h.step()
        assert j.live() is None                 # written every LIVE_EVERY ticks only
        h.step()
        live = j.live()
    assert live["tick"] == LIVE_EVERY
    assert live["poses"] == {"4": [0, 0, 512, -256, 45, 0]}
    assert sum(live["bad_frames"].values()) == 1


# -- (2) and (3): the page in headless chromium -----------------------------------


@pytest.fixture(scope="module")
def browser():
    from bridge.view.browser import headless
    # no skip: a missing chromium fails here, saying `make chromium` installs it.
    # One chromium for the whole file: each test loads its own page.
    driver = headless(1500, 1300)
    yield driver
    driver.quit()


def wait_for(driver, condition):
    from selenium.webdriver.support.ui import WebDriverWait
    return WebDriverWait(driver, HANG_GUARD).until(lambda d: condition(d))


def text(driver, element_id: str) -> str:
    return driver.find_element("id", element_id).text


def canvas_painted(driver) -> bool:
    """Some pixel of the arena is not blank (the page drew on it)."""
    return driver.execute_script(
        "const c = document.getElementById('arena');"
        "const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;"
        "for (let i = 3; i < d.length; i += 4) if (d[i]) return true; return false;")


def test_page_shows_the_arena_then_the_first_touch(sim, browser):
    browser.get(sim.url)
    wait_for(browser, lambda d: d.execute_script("return document.body.dataset.tick") == "0")
    assert text(browser, "touch-count") == "0"
    assert "scenario default, seed 1" in text(browser, "title")
    assert canvas_painted(browser)
    assert browser.find_element("id", "controls").is_displayed()
    summary = {"touches": 0, "finished": False}
    while summary["touches"] == 0 and not summary["finished"]:
        code, summary = post(sim, "/control/step")
        assert code == 200
    assert summary["touches"] >= 1, "the run ended with no touch"
    first = get(sim, "/state.json")["touches"][0]
    n = str(summary["touches"])
    wait_for(browser, lambda d: text(d, "touch-count") == n)
    items = browser.find_elements("css selector", "#touches li.touch")
    assert len(items) == summary["touches"]
    assert items[0].text.startswith(f"robot {first['node']} at tick {first['tick']}")
    assert text(browser, "tick") == str(summary["tick"])
    assert "touch 1 by robot" in text(browser, "events")


def test_page_shows_a_touch_as_it_is_journalled(journal_server, browser):
    server, path = journal_server
    browser.get(server.url)
    wait_for(browser, lambda d: "host journal" in text(d, "title")
             and "HELLO from robot 3" in text(d, "events"))
    assert text(browser, "touch-count") == "0"
    assert not browser.find_element("id", "controls").is_displayed()
    with Journal(path) as j:
        j.add_report(3, msg.TOUCH, (1, 2, 3, 3, 3, 100), 17)
    wait_for(browser, lambda d: text(d, "touch-count") == "1")
    assert text(browser, "touches").startswith("robot 3 at tick 17, segment (3, 3)")
    assert text(browser, "held") == "1.00" and text(browser, "need") == "5.00"
    # the same plots as a simulated run's, from the host's journal
    wait_for(browser, lambda d: json.loads(d.find_element("id", "plot-touches").get_attribute(
        "data-last") or "{}") == {"touches": 1})
    assert not browser.find_elements("id", "plot-shape")     # the host does not know the object
    assert text(browser, "held-word") == "power" and text(browser, "need-word") == "weight"


# -- the command's bad input: one line, exit 2 ---------------------------------------


def run_cli(capsys, *argv: str) -> tuple[int, str]:
    try:
        code = main(["view", *argv])
    except SystemExit as exit_:          # argparse's own errors
        code = exit_.code
    err = capsys.readouterr().err
    return code, err


def test_missing_journal(capsys, tmp_path):
    code, err = run_cli(capsys, "--journal", str(tmp_path / "none.db"))
    assert code == 2 and err.count("\n") == 1
    assert "none.db: no such file" in err


def test_a_file_that_is_not_a_journal(capsys, tmp_path):
    text_file = tmp_path / "notes.txt"
    text_file.write_text("not a database\n" * 100)
    code, err = run_cli(capsys, "--journal", str(text_file))
    assert code == 2 and err.count("\n") == 1 and "notes.txt" in err
    other_db = tmp_path / "other.db"
    with sqlite3.connect(other_db) as db:
        db.execute("CREATE TABLE t (x)")
    code, err = run_cli(capsys, "--journal", str(other_db))
    assert code == 2 and err.count("\n") == 1
    assert "other.db is not a host journal" in err


def test_a_port_in_use(capsys):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        code, err = run_cli(capsys, "--port", str(port), "--paused")
    assert code == 2 and err.count("\n") == 1
    assert f"--port {port}: address already in use" in err


@pytest.mark.parametrize("argv, words", [
    (("--screenshot", "shot.gif"), "expected a .png file"),
    (("--at-tick", "5"), "only with --screenshot"),
    (("--speed", "5000"), "--speed 5000"),
    (("--port", "70000"), "--port"),
    (("--journal", "host.db", "--paused"), "--paused: only for a simulated run"),
])
def test_bad_options(capsys, argv, words):
    code, err = run_cli(capsys, *argv)
    assert code == 2 and err.count("\n") == 1 and words in err


def test_a_missing_browser_fails_saying_how_to_install_it(monkeypatch, tmp_path):
    from bridge.view import browser
    monkeypatch.setattr(browser, "CHROMIUM", tmp_path / "chromium")
    with pytest.raises(browser.BrowserMissing, match="`make chromium` installs Debian's chromium"):
        browser.headless()


def test_screenshot_option_saves_the_page_at_the_tick(capsys, tmp_path):
    out = tmp_path / "live.png"
    assert main(["view", "--screenshot", str(out), "--at-tick", "5", "--port", "0"]) == 0
    assert capsys.readouterr().out.strip() == f"live view at tick 5 saved to {out}"
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# -- the behaviour's own words ---------------------------------------

THESIS_WORDS = ("power", "weight", "IoU", "perceived", "hold the object", "delivered",
                "converged")


def test_an_aggregate_run_shows_its_own_measures_and_no_thesis_words():
    server = ViewServer(SimSource(scenario.load("default").replace(behaviour="aggregate"), SEED),
                        port=0).start()
    try:
        info = get(server, "/info.json")
        assert info["load"] is None and info["shape"] is False
        assert ["clusters", "groups of stopped robots touching each other (8-neighbours)"] \
            in info["measures"]
        post(server, "/control/step", {"ticks": 100})      # past the quorum (tick 54)
        st = get(server, "/state.json")
        assert st["finished"] and "tick 54: DONE" in st["events"]
    finally:
        server.stop()
    titles = {m["name"]: m["title"] for m in st["measures"]}
    assert titles["stopped"] == "robots that stopped" and "largest" in titles
    assert st["measures"][[m["name"] for m in st["measures"]].index("stopped")]["value"] \
        == len(st["touches"])
    # every text the page shows: titles, status, events, the info's words
    said = json.dumps([st["measures"], st["status"], st["events"], info])
    for word in THESIS_WORDS:
        assert word not in said, word
    assert "perceived" not in st and "power" not in st and "iou" not in st


def test_the_thesis_run_shows_its_load_and_shape(sim):
    info = get(sim, "/info.json")
    assert info["load"] == ["power", "weight"] and info["shape"] is True
    st = get(sim, "/state.json")
    assert {"shape_iou", "holders"} <= {m["name"] for m in st["measures"]}
    assert "perceived" in st and "iou" in st


def test_page_of_aggregation_lists_its_measures_and_hides_the_load_bar(browser):
    server = ViewServer(SimSource(scenario.load("default").replace(behaviour="aggregate"), SEED),
                        port=0).start()
    try:
        post(server, "/control/step", {"ticks": 30})
        browser.get(server.url)
        wait_for(browser, lambda d: d.execute_script("return document.body.dataset.tick") == "30")
        wait_for(browser, lambda d: "robots that stopped" in text(d, "measures"))
        shown = text(browser, "measures")
        assert "robots in the largest cluster" in shown and "tick the first robot stopped" in shown
        assert not browser.find_element("id", "load").is_displayed()
        page = browser.find_element("tag name", "body").text
        for word in THESIS_WORDS:
            assert word not in page, word
    finally:
        server.stop()


# -- plots over time, parameters and reset, inspection, axes ----------------

FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures"


def page_tick(driver) -> str:
    return driver.execute_script("return document.body.dataset.tick")


def test_info_lists_plots_and_parameters_from_the_declarations(sim):
    info = get(sim, "/info.json")
    plots = {p["id"]: [s["key"] for s in p["series"]] for p in info["plots"]}
    assert plots["states"] == [f"state:{n}" for n in info["states"]]
    assert plots["load"] == ["power", "weight"] and plots["shape"] == ["shape_iou"]
    assert plots["r-holders"] == ["holders"] and plots["r-home_d2"] == ["home_d2"]
    # the engine's instruments' columns too: perception's shape estimate, as `run` has it
    assert plots["i-estimate_iou"] == ["estimate_iou"]
    params = {p["name"]: p for p in info["params"]}
    assert (params["sigRadius"]["low"], params["sigRadius"]["high"]) == (0, 30)
    assert params["rPower"]["group"] == "behaviour thesis" and params["rPower"]["value"] == 1.0
    assert params["activation"]["choices"] == ["sync", "netlogo"]
    assert "linkLoss" not in params and info["seed"] == SEED
    post(sim, "/control/step", {"ticks": 40})
    cols = get(sim, "/state.json")["plots"]
    assert cols["tick"][0] == 0 and cols["tick"][-1] == 40
    assert all(sum(cols[f"state:{n}"][i] for n in info["states"]) == 20
               for i in range(len(cols["tick"])))


def test_aggregation_gets_its_own_plots():
    server = ViewServer(SimSource(scenario.load("default").replace(behaviour="aggregate"), SEED),
                        port=0).start()
    try:
        info = get(server, "/info.json")
        ids = [p["id"] for p in info["plots"]]
        assert "load" not in ids and "shape" not in ids and "states" in ids
        assert {p["name"] for p in info["params"]} >= {"sigRadius", "agents"}
        assert not any(p["group"] == "behaviour thesis" for p in info["params"])
    finally:
        server.stop()


def test_reset_takes_the_cli_s_values_and_errors(sim, capsys):
    post(sim, "/control/step", {"ticks": 5})
    code, s = post(sim, "/control/reset", {"set": ["sigRadius=99"]})
    assert code == 400 and get(sim, "/state.json")["tick"] == 5      # nothing happened
    assert main(["run", "--set", "sigRadius=99"]) == 2
    assert capsys.readouterr().err == f"touchswarm: error: {s['error']}\n"
    code, s = post(sim, "/control/reset", {"seed": -1})
    assert code == 400 and "--seed -1: outside 0..1000002" in s["error"]
    code, s = post(sim, "/control/reset", {"set": ["rPower=2", "sigRadius=6"], "seed": 3})
    assert code == 200 and s["tick"] == 0 and s["playing"] is False
    info = get(sim, "/info.json")
    assert info["seed"] == 3 and "seed 3" in info["title"]
    values = {p["name"]: p["value"] for p in info["params"]}
    assert values["rPower"] == 2.0 and values["sigRadius"] == 6
    assert get(sim, "/state.json")["plots"]["tick"] == [0]


def test_robot_inspector_and_claimed_cells(sim):
    post(sim, "/control/step", {"ticks": 60})
    st = get(sim, "/state.json")
    r = get(sim, "/robot.json?node=4")
    assert r["node"] == 4 and r["tick"] == 60
    assert r["state"] == get(sim, "/info.json")["states"][st["robots"][3]["state"]]
    assert (r["x"], r["y"]) == (st["robots"][3]["x"], st["robots"][3]["y"])
    assert 0 <= r["heading"] < 360 and r["variables"]
    assert all(m["way"] in ("sent", "received") and m["tick"] <= 60 for m in r["messages"])
    assert r["messages"][0]["text"].startswith("HELLO (model")     # its first word to the host
    holders = {t["node"] for t in st["touches"]}
    assert {c[2] for c in st["claimed"]} <= holders
    assert all([c[0], c[1]] in st["object"] for c in st["claimed"])
    with pytest.raises(urllib.error.HTTPError):
        get(sim, "/robot.json?node=21")


def test_favicon_is_served(sim):
    with urllib.request.urlopen(sim.url + "favicon.ico", timeout=HANG_GUARD) as r:
        assert r.status == 200 and b"<svg" in r.read()


def test_journal_plots_halts_and_one_line_per_decision(journal_server):
    server, path = journal_server
    with Journal(path) as j:
        j.add_report(3, msg.TOUCH, (1, 2, 3, 3, 3, 100), 17)
        for t in (30, 31, 32):      # the host repeats its halt decision tick after tick
            j.add_decision(t, "halt", {"coordinator": {"delivered_tick": 30},
                                       "host": {"halts_sent": t - 29}})
        j.set_live({"tick": 40, "poses": {"3": [19, 3, 512, 768, 90, 0]}, "bad_frames": {}})
    st = get(server, "/state.json")
    assert [e for e in st["events"] if "decision" in e] == \
        ["tick 30: decision halt (repeated to tick 32, 3 times)"]
    halt = get(server, "/info.json")["states"].index("halt")
    assert st["robots"][0]["state"] == halt and st["robots"][0]["halted"] is True
    cols = st["plots"]
    assert cols["tick"][-1] == 40 and cols["touches"][-1] == 1 and cols["power"][-1] == 1.0
    assert cols["state:halt"][-1] == 1
    assert "shape" not in [p["id"] for p in get(server, "/info.json")["plots"]]


def test_page_sets_a_parameter_runs_to_delivery_and_inspects(sim, browser, capsys):
    """The view's whole promise in one page: a bad value shows the CLI's
    line, a good one resets the run, the run is played to delivery, the
    plots' last values are the run's summary, a clicked robot shows its
    state; each panel is saved under docs/figures for docs/view.md."""
    from selenium.webdriver.common.action_chains import ActionChains
    from sim_backend.engine import run as run_engine
    browser.get(sim.url)
    wait_for(browser, lambda d: page_tick(d) == "0")
    field = browser.find_element("id", "param-sigRadius")
    field.clear()
    field.send_keys("99")
    browser.find_element("id", "reset").click()
    wait_for(browser, lambda d: text(d, "param-error"))
    assert main(["run", "--set", "sigRadius=99"]) == 2
    assert capsys.readouterr().err == f"touchswarm: error: {text(browser, 'param-error')}\n"
    field.clear()
    field.send_keys("5")
    power = browser.find_element("id", "param-rPower")
    power.clear()
    power.send_keys("2")
    browser.find_element("id", "reset").click()
    # the page reloads the parameters after a reset: wait for the new values
    wait_for(browser, lambda d: d.execute_script(
        "return info.params.find((p) => p.name === 'rPower').value") == 2)
    assert text(browser, "param-error") == ""
    assert sim.source.sc.rPower == 2.0
    summary = run_engine(sim.source.sc, SEED).summary()     # what summary.json holds
    speed = browser.find_element("id", "speed")
    speed.clear()
    speed.send_keys("1000\n")
    wait_for(browser, lambda d: sim.source.speed == 1000)
    browser.find_element("id", "play").click()
    wait_for(browser, lambda d: text(d, "playing") == "finished"
             and page_tick(d) == str(summary["ticks"])
             and d.find_element("id", "plot-touches").get_attribute("data-tick")
             == str(summary["ticks"]))
    assert summary["delivered"] and "DELIVERED" in text(browser, "events")

    def last(plot: str) -> dict:
        return json.loads(browser.find_element("id", f"plot-{plot}").get_attribute("data-last"))
    assert last("touches") == {"touches": len(summary["touches"])}
    assert last("load") == {"power": summary["power"], "weight": 5.0}
    assert last("shape")["shape_iou"] == pytest.approx(summary["shape_iou"])
    assert sum(last("states").values()) == summary["robots"]
    assert f"touches {len(summary['touches'])}" in text(browser, "last-touches")

    # click robot 7 where the page draws it
    robot = get(sim, "/state.json")["robots"][6]
    canvas = browser.find_element("id", "arena")
    px, py = browser.execute_script(
        "const g = geometry(document.getElementById('arena'));"
        "return [g.px(arguments[0]), g.py(arguments[1])];", robot["x"], robot["y"])
    size = canvas.size
    ActionChains(browser).move_to_element_with_offset(
        canvas, int(px - size["width"] / 2), int(py - size["height"] / 2)).click().perform()
    wait_for(browser, lambda d: text(d, "insp-node") == "7" and text(d, "insp-state"))
    assert text(browser, "insp-state") == get(sim, "/robot.json?node=7")["state"]
    assert "heading" in text(browser, "insp-vars")
    # hover over a held cell: who holds it
    st = get(sim, "/state.json")
    assert st["claimed"], "the holders let go at delivery"
    x, y, node = st["claimed"][0]
    px, py = browser.execute_script(
        "const g = geometry(document.getElementById('arena'));"
        "return [g.px(arguments[0]), g.py(arguments[1])];", x, y)
    ActionChains(browser).move_to_element_with_offset(
        canvas, int(px - size["width"] / 2), int(py - size["height"] / 2)).perform()
    wait_for(browser, lambda d: f"held by robot {node}" in text(d, "hover"))

    FIGURES.mkdir(exist_ok=True)
    for element, name in (("arena-col", "view_arena"), ("plots", "view_plots"),
                          ("params", "view_params"), ("inspect", "view_inspect")):
        browser.find_element("id", element).screenshot(str(FIGURES / f"{name}.png"))
    # zoom in about the arena's centre (the wheel), then back (double-click)
    zoom = browser.execute_script(
        "const c = document.getElementById('arena'); const r = c.getBoundingClientRect();"
        "c.dispatchEvent(new WheelEvent('wheel', {deltaY: -100, clientX: r.left + 320,"
        " clientY: r.top + 320, bubbles: true, cancelable: true}));"
        "return window.view.zoom;")
    assert zoom == 1.25
    browser.execute_script("document.getElementById('arena').dispatchEvent("
                           "new MouseEvent('dblclick', {bubbles: true}));")
    assert browser.execute_script("return window.view.zoom") == 1


def test_the_live_view_draws_the_hosts_estimate_as_world_png_does(sim):
    """The estimate where the object is now, with its verdict, the
    same cells world.png and the animation draw (sim_backend/render.py)."""
    from sim_backend import render
    assert "estimate" not in get(sim, "/state.json")          # nothing touched yet
    post(sim, "/control/step", {"ticks": 120})
    st = get(sim, "/state.json")
    assert st["tick"] == 120 and st["estimate"] and st["verdict"]
    src = sim.source
    cells, recognised, p = render.estimate_of(src.engine.instruments)
    dx, dy = render.displacement(src.engine.world)
    assert st["estimate"] == [[x + dx, y + dy] for x, y in sorted(cells)]
    assert st["verdict"] == render.verdict_text(recognised, p)
    info = get(sim, "/info.json")
    assert info["source"] == "sim"
