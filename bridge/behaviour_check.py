"""`touchswarm behaviour check DIR`: every step a behaviour must pass, run as
a user runs it (the real CLI, one subprocess a step), with a table of
pass/fail and the first error line of each.

The steps, in order; a step whose prerequisite failed is not run:

    load      the registry loads it; its PARAMS are valid scenario keys
    run       the reference engine, --ticks ticks
    sweep     the compiled soa engine and the reference engine, 2 seeds:
              every run's ticks and measures identical
    firmware  `firmware check`: subset, mpy-cross, CPython == MicroPython,
              every state visited, 0 heap bytes per step
    can       `run --link can --record`, then `replay`: 0 divergences
    dbc       `dbc --behaviour`: cantools loads it and knows its messages
    bus       `robots` behind an SLCAN face on a pty and `host` on it: two
              processes; the host finishes (its coordinator's done()) or
              stops at --ticks, both exit cleanly
    deploy    `deploy --behaviour` to --port (not run without one): the board
              imports the behaviour as the package behaviour/ and builds its
              robot
    mission   `deploy --start` on --port, then `mission --body 1=mpy://PORT`:
              the board's robot beside simulated ones, one host
"""

from __future__ import annotations

import csv
import logging
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

log = logging.getLogger(__name__)

EXE = str(Path(sys.executable).with_name("touchswarm"))
STEPS = ("load", "run", "sweep", "firmware", "can", "dbc", "bus", "deploy", "mission")
NEEDS = {"sweep": "run", "can": "run", "bus": "run", "firmware": "load", "run": "load",
         "dbc": "load", "deploy": "firmware", "mission": "deploy"}
COMPILE_TIMEOUT_S = 1200.0     # a new behaviour's soa compile (1.5-3.5 min, more when busy)
STEP_TIMEOUT_S = 600.0


class StepFailed(Exception):
    """A step's first error, one line."""


@dataclass
class Outcome:
    step: str
    status: str          # PASS, FAIL, NOT RUN
    seconds: float
    detail: str


def _first_error(text: str) -> str:
    lines = [ln.strip() for ln in text.strip().splitlines() if ln.strip()]
    for ln in lines:
        if "error" in ln.lower() or "FAIL" in ln:
            return ln
    return lines[-1] if lines else "(no output)"


def cli(*args: str, timeout: float = STEP_TIMEOUT_S, cwd: Path | None = None) -> str:
    """Run `touchswarm ARGS`; its stdout, or StepFailed with its first error."""
    try:
        p = subprocess.run([EXE, *args], capture_output=True, text=True, timeout=timeout,
                           cwd=cwd)
    except subprocess.TimeoutExpired:
        raise StepFailed(f"`touchswarm {' '.join(args[:2])} ...` took more than "
                         f"{timeout:g} s") from None
    if p.returncode != 0:
        raise StepFailed(f"`touchswarm {args[0]}` exit {p.returncode}: "
                         f"{_first_error(p.stderr or p.stdout)}")
    return p.stdout


class Checker:
    def __init__(self, folder: Path, work: Path, ticks: int, port: str | None) -> None:
        self.folder = folder
        self.work = work
        self.ticks = ticks
        self.port = port
        self.sc = ["--behaviour", str(folder), "--set", f"maxTicks={ticks}"]

    def load(self) -> str:
        from sim_backend import registry
        from sim_backend import scenario
        from sim_backend.errors import ScenarioError
        try:
            b = registry.load(str(self.folder))
            sc = scenario.validate({"behaviour": str(self.folder)})
            b.robot_args(1, 1, sc)       # they fit the FSM's constructor
        except (registry.BehaviourError, ScenarioError) as err:
            raise StepFailed(str(err)) from None
        return (f"{b.name}: {len(b.spec.STATES)} states, {len(sc.params)} parameters, "
                f"{len(getattr(b.spec, 'MESSAGES', ()))} own messages")

    def run(self) -> str:
        import json
        s = json.loads(cli("run", *self.sc, "--json").strip().splitlines()[-1])
        return f"{s['ticks']} ticks"

    def sweep(self) -> str:
        rows = {}
        for engine in ("soa", "reference"):
            out = self.work / f"sweep-{engine}"
            cli("sweep", "--set", f"behaviour={self.folder}", "--set",
                f"maxTicks={self.ticks}", "--seeds", "2", "--engine", engine, "--no-plots",
                "--out", str(out), timeout=COMPILE_TIMEOUT_S)
            with open(out / "sweep.csv", newline="") as f:
                rows[engine] = list(csv.DictReader(f))
        if len(rows["soa"]) != len(rows["reference"]):
            raise StepFailed(f"soa wrote {len(rows['soa'])} runs, reference "
                             f"{len(rows['reference'])}")
        for a, b in zip(rows["soa"], rows["reference"]):
            differ = [k for k in a if k != "engine" and a[k] != b.get(k)]
            if differ:
                raise StepFailed(f"seed {a.get('seed')}: soa and reference differ in "
                                 f"{differ[0]} ({a[differ[0]]} vs {b.get(differ[0])})")
        return f"soa == reference over {len(rows['soa'])} runs"

    def firmware(self) -> str:
        out = cli("firmware", "check", "--behaviour", str(self.folder), timeout=COMPILE_TIMEOUT_S)
        return out.strip().splitlines()[-1] if out.strip() else "PASS"

    def can(self) -> str:
        rec = self.work / "run.blf"
        cli("run", *self.sc, "--link", "can", "--record", str(rec))
        # the folder under check is the user's own: trusted (docs/security.md)
        out = cli("replay", str(rec), "--trust-behaviour", str(self.folder))
        return _first_line(out, "divergence") or "replayed"

    def dbc(self) -> str:
        import cantools
        path = self.work / "behaviour.dbc"
        cli("dbc", "--behaviour", str(self.folder), "--out", str(path))
        db = cantools.database.load_file(str(path))
        assert isinstance(db, cantools.database.can.Database)    # a .dbc file: CAN messages
        from sim_backend import registry
        own = [row[1] for row in getattr(registry.load(str(self.folder)).spec, "MESSAGES", ())]
        names = {m.name for m in db.messages}
        missing = [n for n in own if not any(n in x for x in names)]
        if missing:
            raise StepFailed(f"the DBC lacks the behaviour's message {missing[0]}")
        return f"{len(db.messages)} messages"

    def bus(self) -> str:
        import json
        import signal
        adapter = self.work / "adapter"
        # the robots tick from the start, the host joins when it has started
        # (seconds on a busy machine): they run long enough to meet it, and
        # the host's HALT (or a SIGTERM once the host gave up) ends them
        robots = subprocess.Popen([EXE, "robots", "--bus", f"slcan-pty://{adapter}",
                                   "--behaviour", str(self.folder), "--set",
                                   f"maxTicks={self.ticks * 50}", "--tick-ms", "4",
                                   "--linger-ms", "500", "--json"],
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            _wait_for_path(adapter, robots, 60.0)
            host = subprocess.run([EXE, "host", "--bus", f"slcan://{adapter}?settle_ms=0",
                                   *self.sc, "--tick-ms", "4", "--max-ticks", str(self.ticks),
                                   "--json"], capture_output=True, text=True,
                                  timeout=STEP_TIMEOUT_S)
            if robots.poll() is None and host.returncode != 0:
                robots.send_signal(signal.SIGTERM)     # no HALT came: stop them cleanly
            rout, rerr = robots.communicate(timeout=120)
        finally:
            if robots.poll() is None:
                robots.kill()
                robots.wait(10)
        if host.returncode not in (0, 1):            # 1: the goal not reached in --ticks
            raise StepFailed(f"`touchswarm host` exit {host.returncode}: "
                             f"{_first_error(host.stderr or host.stdout)}")
        if robots.returncode not in (0, 1):          # 1: not every robot halted
            raise StepFailed(f"`touchswarm robots` exit {robots.returncode}: "
                             f"{_first_error(rerr)}")
        h = json.loads(host.stdout.strip().splitlines()[-1])
        r = json.loads(rout.strip().splitlines()[-1])
        if not h.get("messages"):
            raise StepFailed("the host heard no robot over the bus")
        return (f"host: {h['ticks']} ticks, {h['messages']} messages, "
                f"{'done' if h.get('delivered') else 'not done'}; robots "
                f"{'all halted' if r['halted'] else 'not all halted'}")

    def deploy(self) -> str:
        if self.port is None:
            raise NotRun("give --port PORT (a MicroPython board) to deploy")
        out = cli("deploy", "--behaviour", str(self.folder), "--port", self.port)
        return _first_line(out, "imported") or out.strip().splitlines()[-1]

    def mission(self) -> str:
        import json
        if self.port is None:
            raise NotRun("give --port PORT (a MicroPython board) for a mission")
        cli("deploy", "--behaviour", str(self.folder), "--port", self.port, "--config",
            "NODE=1", "--config", f"MAX_TICKS={self.ticks + 200}", "--config", "LINGER=2",
            "--start")
        p = subprocess.run([EXE, "mission", "--body", f"1=mpy://{self.port}", *self.sc,
                            "--robots", "6", "--tick-ms", "20", "--max-ticks",
                            str(min(self.ticks, 200)), "--json"],
                           capture_output=True, text=True, timeout=STEP_TIMEOUT_S)
        if p.returncode not in (0, 1):       # 1: the behaviour's goal not reached, no error
            raise StepFailed(f"`touchswarm mission` exit {p.returncode}: "
                             f"{_first_error(p.stderr or p.stdout)}")
        s = json.loads(p.stdout.strip().splitlines()[-1])
        body = s.get("bodies", {}).get("1", "")
        if not body.startswith("MicroPython robot"):
            raise StepFailed(f"robot 1 is not the board: {body!r}")
        return f"{s['ticks']} ticks, robot 1 on the board"


class NotRun(Exception):
    """A step that needs something this check was not given."""


def _first_line(text: str, needle: str) -> str:
    return next((ln.strip() for ln in text.splitlines() if needle in ln), "")


def _wait_for_path(path: Path, proc: subprocess.Popen, timeout: float) -> None:
    """Until the robots' pty face exists (a condition, not a sleep)."""
    end = time.monotonic() + timeout
    while not path.exists():
        if proc.poll() is not None:
            raise StepFailed(f"`touchswarm robots` exit {proc.returncode}: "
                             f"{_first_error(proc.stderr.read() if proc.stderr else '')}")
        if time.monotonic() > end:
            raise StepFailed(f"`touchswarm robots` made no pty face in {timeout:g} s")
        time.sleep(0.05)


def check(folder: Path, ticks: int = 400, port: str | None = None,
          steps: tuple[str, ...] = STEPS,
          on_step: Callable[[Outcome], None] | None = None) -> list[Outcome]:
    """Every step on the behaviour folder, in order."""
    out: list[Outcome] = []
    passed: set[str] = set()
    with tempfile.TemporaryDirectory(prefix="touchswarm-check-") as tmp:
        c = Checker(folder.resolve(), Path(tmp), ticks, port)
        for step in steps:
            need = NEEDS.get(step)
            t0 = time.monotonic()
            if need is not None and need in steps and need not in passed:
                o = Outcome(step, "NOT RUN", 0.0, f"needs {need}")
            else:
                try:
                    detail = getattr(c, step)()
                    o = Outcome(step, "PASS", time.monotonic() - t0, detail)
                    passed.add(step)
                except NotRun as err:
                    o = Outcome(step, "NOT RUN", 0.0, str(err))
                except StepFailed as err:
                    o = Outcome(step, "FAIL", time.monotonic() - t0, str(err))
                except Exception as err:   # noqa: BLE001 - a check reports, never crashes
                    log.debug("step %s", step, exc_info=True)
                    o = Outcome(step, "FAIL", time.monotonic() - t0,
                                f"{type(err).__name__}: {err}".splitlines()[0])
            out.append(o)
            if on_step is not None:
                on_step(o)
    return out
