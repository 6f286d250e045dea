"""Frames per second of the live view (`touchswarm view`) at 1,000 robots,
in Debian's headless chromium (the browser test's; `make venv` installs it).

The simulated run (1,000 robots in the arena scaled to their number,
arena_presets.scaled_world) is stepped to TICKS (or its end) and the page loaded; then, in
the page:
  draw_fps       arena redraws per second (field, object, robots, touches,
                 axes): what zoom and pan cost per frame
  frame_fps      whole updates per second: fetch /state.json, parse it, draw
                 the arena, the plots and the side panel (the poll's work,
                 with no wait between)
and, in Python, the server's milliseconds per /state.json at that size.
Reported, not asserted (wall clock). Prints one JSON object.

    .venv/bin/python bench/view_fps.py [--robots 1000]
"""

import argparse
import json
import os
import sys
import time
import urllib.request

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from bridge.view.browser import headless  # noqa: E402
from bridge.view.server import ViewServer  # noqa: E402
from bridge.view.sources import SimSource  # noqa: E402
from sim_backend import scenario  # noqa: E402
from sim_backend.arena_presets import scaled_world  # noqa: E402

TICKS = 100
FRAMES = 60

MEASURE = """
const done = arguments[arguments.length - 1];
(async () => {
  let t = performance.now();
  for (let i = 0; i < arguments[0]; i++) draw();
  const drawS = (performance.now() - t) / 1000;
  t = performance.now();
  for (let i = 0; i < arguments[0]; i++) {
    const st = await (await fetch('/state.json')).json();
    view.st = st; draw(); plots(st.plots); panel(st);
  }
  const frameS = (performance.now() - t) / 1000;
  done([arguments[0] / drawS, arguments[0] / frameS, view.st.robots.length]);
})();
"""


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--robots", type=int, default=1000)
    args = ap.parse_args()
    sc = scenario.load("default").replace(agents=args.robots, worldSize=scaled_world(args.robots))
    server = ViewServer(SimSource(sc, 1), port=0).start()
    driver = headless(1500, 1100)
    try:
        tick = server.source.control("step", {"ticks": TICKS})["tick"]   # or its end
        start = time.perf_counter()
        for _ in range(10):
            with urllib.request.urlopen(server.url + "state.json") as r:
                size = len(r.read())
        state_ms = (time.perf_counter() - start) / 10 * 1e3
        driver.get(server.url)
        driver.set_script_timeout(600)
        from selenium.webdriver.support.ui import WebDriverWait
        WebDriverWait(driver, 120).until(
            lambda d: d.execute_script("return document.body.dataset.tick") == str(tick))
        draw_fps, frame_fps, robots = driver.execute_async_script(MEASURE, FRAMES)
    finally:
        driver.quit()
        server.stop()
    print(json.dumps({"robots": robots, "worldSize": sc.worldSize, "tick": tick,
                      "frames": FRAMES, "draw_fps": round(draw_fps, 1),
                      "frame_fps": round(frame_fps, 1),
                      "state_json_ms": round(state_ms, 1), "state_json_kb": round(size / 1024)}))


if __name__ == "__main__":
    main()
