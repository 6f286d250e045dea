"""What the host's live view (poses, bad frames for `touchswarm view`) costs
per write, beside a durable journal write (a report before its ACK).

Prints one JSON object: milliseconds per write of each, and the host-tick
share the live view takes at the 10 ms tick (written every LIVE_EVERY ticks).

    .venv/bin/python bench/journal_live.py
"""

import json
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from bridge.host.journal import Journal  # noqa: E402
from bridge.host.process import LIVE_EVERY  # noqa: E402
from firmware_logic import messages as msg  # noqa: E402

WRITES = 200
ROBOTS = 20


def per_write_ms(fn) -> float:
    start = time.perf_counter()
    for i in range(WRITES):
        fn(i)
    return (time.perf_counter() - start) / WRITES * 1e3


def main() -> None:
    with tempfile.TemporaryDirectory() as d, Journal(os.path.join(d, "j.sqlite")) as j:
        j.bind("thesis")
        view = {"poses": {str(n): [0, 0, 256 * n, -256, 90, 0] for n in range(1, ROBOTS + 1)},
                "bad_frames": {}, "messages": 0}
        live = per_write_ms(lambda i: j.set_live({"tick": i, **view}))
        durable = per_write_ms(lambda i: j.add_report(1, msg.HELLO, (1, 100, 1), i))
    print(json.dumps({"robots": ROBOTS, "writes": WRITES,
                      "live_view_ms_per_write": round(live, 3),
                      "durable_report_ms_per_write": round(durable, 3),
                      "live_view_share_of_10ms_ticks": round(live / (10.0 * LIVE_EVERY), 4)}))


if __name__ == "__main__":
    main()
