"""The HAL contract (tests/test_hal_contract.py) against the replay body:
`ReplayHal` (bridge/record/replay.py), which answers the firmware from a
recorded sensor stream and raises Diverged when asked for a reading the
recording does not hold next.

A replay can only answer what was recorded, so each clause is recorded
first: the same clause runs against the simulated body of a recording
engine (bridge/record/recorder.py, what `touchswarm run --record` uses),
written to a python-can log with its sidecar; then the clause runs again
against a ReplayHal over that file, read back with replay's own `load()`.
Every tick of the replay is checked as `replay()` checks a robot's tick:
all recorded readings asked for, the same actions, the same messages sent.
A replay that answered a reading wrongly (a wrong query code, the argument
for the value, a message lost) fails the clause or diverges.
"""

from __future__ import annotations

from collections import deque
from contextlib import ExitStack
from pathlib import Path
from typing import Callable

import pytest

from bridge.record.recorder import Recorder, recording_engine
from bridge.record.replay import Recording, ReplayHal, load
from firmware_logic import hal as H
from sim_backend.engine import InprocLink
from sim_backend.scenario import validate
from tests.test_hal_contract import SCENARIO, HalContract, placed

NODE = 1
SEED = 1


class RecordedSim(HalContract):
    """A clause run against robot 1 of a recording engine, each tick written
    to `path` as the recorder writes a run's ticks."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.recorder: Recorder | None = None

    def make(self) -> tuple[H.Hal, Callable[[], None]]:
        sc = validate(SCENARIO)
        rec = self.recorder = Recorder(self.path, sc, SEED)
        eng = recording_engine(sc, SEED, InprocLink(list(range(1, sc.agents + 1))), rec)
        placed(eng.world)
        body = eng.bodies[0]
        body.reset_intents()
        self.engine = eng

        def tick():
            eng._apply()
            eng.exchange()
            self.flush()
            eng.tick += 1
            body.reset_intents()
        eng.tick = 1              # ticks count from 1, as in a run
        return body, tick

    def flush(self) -> None:
        """Write what robot 1 read, did and sent since the last tick."""
        eng = self.engine
        assert self.recorder is not None
        self.recorder.write_tick(eng.tick, eng.bodies, *eng.link.take())


class TestReplayHal(HalContract):
    def setup_method(self, method: Callable[..., None]) -> None:
        self.clause = method.__name__

    @pytest.fixture(autouse=True)
    def _tmp(self, tmp_path: Path) -> None:
        self.tmp = tmp_path

    def record(self) -> Recording | None:
        """Run this clause against the recording sim body; its recording
        (None: the clause read and did nothing, so there is nothing to replay)."""
        twin = RecordedSim(self.tmp / "clause.log")
        getattr(twin, self.clause)()
        if twin.recorder is None:
            return None
        twin.flush()                  # the readings after the clause's last tick
        twin.recorder.close()
        return load(twin.path) if twin.recorder.frames else None

    def make(self):
        rec = self.record()
        inbox: deque = deque()
        hal = ReplayHal(NODE, inbox)
        t = [1]

        def feed() -> None:
            if rec is not None:
                hal.tape = deque(rec.sensors[NODE].get(t[0], []))

        def check() -> None:
            # what replay() checks at the end of a robot's tick
            want_acts = rec.actions[NODE].get(t[0], []) if rec is not None else []
            want_sent = ([m for m in rec.up.get(t[0], []) if m[0] == NODE]
                         if rec is not None else [])
            assert not hal.tape, f"tick {t[0]}: recorded readings never asked: {hal.tape}"
            assert hal.acts == want_acts
            assert hal.sent == want_sent

        def tick():
            check()
            if rec is not None:
                for node, kind, f in rec.down.get(t[0], []):
                    if node in (0, NODE):
                        inbox.append((kind, f))
            t[0] += 1
            hal.acts, hal.sent = [], []
            feed()

        feed()
        # the clause's last tick is checked when it ends: every reading used
        self.stack = ExitStack()
        self.stack.callback(check)
        return hal, tick
