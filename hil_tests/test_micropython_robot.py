"""The firmware on real MicroPython behind a pty, deployed with `touchswarm deploy`,
run against the host coordinator over the framed serial link, its sensors
fed by the sim world (sim_backend/emulators/tether.py).

Faults (garbage both ways, truncated frames, the port vanishing and coming
back) are injected through the pty relay; every run must end with the touch
journalled exactly once and acknowledged (the robot stops retransmitting).
"""

from __future__ import annotations

import re
import tempfile
import time
from pathlib import Path
from typing import Callable

import pytest

from bridge.cli import main as cli_main
from bridge.host.journal import Journal
from bridge.serial.deploy import Deployer, DeployError
from bridge.serial.pty import PtyRelay
from bridge.serial.transport import SerialTransport
from firmware_logic import fixedpoint as fx
from firmware_logic import messages as msg
from firmware_logic.behaviours.thesis.coordinator import Coordinator, Touch
from sim_backend import registry
from sim_backend import scenario
from sim_backend.emulators.tether import TetherTransport
from sim_backend.engine import Engine

SEED = 3
# hang guards only (wall clock; a loaded machine runs the unix port slowly):
# every wait below is on a condition, never on a duration
HANG_GUARD_S = 120.0


def mission_scenario() -> scenario.Scenario:
    # two robots so one touch (power 1.0) does not reach the weight 2.0:
    # the run ends when the host has journalled and acknowledged the touch
    return scenario.load("default").replace(agents=2, objectWeight=2.0, objectX=0, objectY=0)


def mission_engine() -> Engine:
    eng = Engine(mission_scenario(), SEED)
    w = eng.world
    # robot 1 (tethered) starts two patches west of the bar; robot 2 stays put
    w.xs[0], w.ys[0] = fx.ONE * -1, 0
    if fx.patch(w.xs[1]) == -1 and fx.patch(w.ys[1]) == 0:
        w.xs[1], w.ys[1] = fx.ONE * -10, fx.ONE * -10
    w.recount()
    return eng


def deploy_and_start(dev: PtyRelay, max_ticks: int = 3000, **extra: int) -> None:
    # the robot's arguments: the thesis's robot_args over the mission's scenario
    Deployer(dev.path).deploy({"NODE": 1, "SEED": SEED, "MAX_TICKS": max_ticks,
                               "LINGER": 2, **extra}, mission_scenario())
    Deployer(dev.path).start()


class Mission:
    """The host side: coordinator + journal over SerialTransport + tether."""

    def __init__(self, dev: PtyRelay) -> None:
        self.dev = dev
        self.engine = mission_engine()
        self.journal: list[Touch] = []
        # the host process's own SQLite (WAL) journal, written before the ACK
        self.journal_path = Path(tempfile.mkdtemp()) / "host-journal.sqlite"
        self.db = Journal(self.journal_path)
        self.journalled_at = -1      # robot ticks applied when the touch was journalled
        self.coord = Coordinator(self.engine.sc.weight_centi, journal=self._journal)
        self.serial = SerialTransport(dev.path, 115200, timeout=0.02, reopen_every=0.05)
        self.link = TetherTransport(self.serial, self.engine, [1])
        self.tick = 0
        self.touch_msgs = 0

    def _journal(self, node: int, kind: int, f: tuple, tick: int) -> None:
        self.db.add_report(node, kind, f, tick)
        if kind != msg.TOUCH:
            return
        self.journal.append(Touch(node, *f, tick))
        if self.journalled_at < 0:
            self.journalled_at = self.link.applied_ticks

    def run(self, until: Callable[["Mission"], bool], limit_s: float = HANG_GUARD_S,
            fault: Callable[["Mission"], None] | None = None) -> None:
        end = time.monotonic() + limit_s
        while not until(self):
            assert time.monotonic() < end, (
                "mission did not finish: %d robot ticks, journal %r, bad frames %r"
                % (self.link.applied_ticks, self.journal, self.serial.bad_frames()))
            for node, kind, f in self.link.poll(0.02):
                if kind == msg.TOUCH:
                    self.touch_msgs += 1
                self.coord.on_message(node, kind, f, self.tick)
            self.tick += 1
            for node, kind, f in self.coord.tick(self.tick):
                self.link.send(node, kind, f)
            if fault is not None:
                fault(self)

    def halt_and_inspect(self) -> dict[str, int]:
        """HALT the robot, serve its last ticks until its loop has ended (its
        ACTION STOP frame, board.run), then read its counters over the REPL.
        Not silence: a robot waiting for an answer is silent too, and one
        still in its loop swallows the REPL's Ctrl-C / Ctrl-A as link bytes."""
        end = time.monotonic() + HANG_GUARD_S
        while 1 not in self.link.stopped:
            assert time.monotonic() < end, (
                "the robot's loop never ended after HALT: %d robot ticks, bad frames %r"
                % (self.link.applied_ticks, self.serial.bad_frames()))
            self.link.send(msg.HOST, msg.HALT, (0,))
            self.link.poll(0.1)
        self.link.close()
        out = Deployer(self.dev.path).exec(
            "import main; h = main.LAST['hal']; r = h.robot; "
            "print('state', r.state); print('pending', r.pending); print('seq', r.seq); "
            "print('lost', h.lost); print('resent', h.resent); print('ticks', h.tick)")
        return {k: int(v) for k, v in re.findall(r"^(\w+) (-?\d+)\s*$", out, re.M)}

    def close(self) -> None:
        self.link.close()
        self.db.close()


def acked(m: Mission) -> bool:
    # journalled, and the robot has had time to see the ACK: no TOUCH
    # retransmission for a while
    return bool(m.journal) and m.link.applied_ticks > m.journalled_at + 80


def check_outcome(m: Mission, robot: dict[str, int]) -> None:
    assert len(m.journal) == 1, m.journal
    t = m.journal[0]
    assert t.node == 1 and t.seq == 1
    assert (t.sx, t.sy) in m.engine.world.object_cells
    assert [x.as_tuple() for x in m.coord.touches] == [t.as_tuple()]
    with Journal(m.journal_path) as db:        # durable, as a restarted host reads it
        assert [(r.node,) + r.fields for r in db.reports(msg.TOUCH)] == [(1,) + t.report()]
    assert robot["state"] == 5, robot           # HALT
    assert robot["pending"] == 0, robot         # the acknowledged touch is known acked
    assert robot["seq"] == 1, robot


def test_deploy_command_prints_bytes_and_verifies(micropython_device: PtyRelay,
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    rc = cli_main(["deploy", "--port", micropython_device.path, "--config", "NODE=4"])
    out, err = capsys.readouterr()
    assert rc == 0, out + err
    m = re.search(r"deployed (\d+) bytes in (\d+) files", out)
    assert m, out
    flash = micropython_device.flash   # type: ignore[attr-defined]
    on_disk = sum(p.stat().st_size for p in flash.rglob("*") if p.is_file())
    assert int(m.group(1)) == on_disk
    files = sorted(p.relative_to(flash).as_posix() for p in flash.rglob("*") if p.is_file())
    # the firmware core, the thesis as the package behaviour/ (its host side left
    # behind), main.py and robot_config.py
    assert int(m.group(2)) == len(files) and out.count("verified") == len(files)
    assert "firmware_logic/board.mpy" in files and "behaviour/robot.mpy" in files
    assert "behaviour/coordinator.mpy" not in files
    assert not any("behaviours" in f for f in files)
    config = (flash / "robot_config.py").read_text()
    args = registry.load("thesis").robot_args(4, 1, scenario.validate({"behaviour": "thesis"}))
    assert config == ("ARGS = %r\nBEHAVIOUR = 'thesis'\nNODE = 4\nSEED = 1\n" % (args,))
    # verified by importing on the device: main.build made the robot from ARGS
    assert f"imported thesis on the device and built its robot (Robot, {len(args)} arguments, " \
        "state search)" in out
    assert "kept" not in out
    # a redeploy without --config keeps the old configuration, and says so
    assert cli_main(["deploy", "--port", micropython_device.path]) == 0
    out = capsys.readouterr().out
    assert "kept the device's robot_config.py from an earlier deploy (" in out
    assert "NODE=4" in out and "imported thesis" in out
    assert (flash / "robot_config.py").read_text() == config


def test_deploy_refuses_a_device_with_another_mpy_version(micropython_device: PtyRelay,
                                                          tmp_path) -> None:
    # a device that reports .mpy v5 (MicroPython 1.12..1.18)
    d = Deployer(micropython_device.path)
    d.exec = lambda code: "5\n"          # type: ignore[method-assign]
    with pytest.raises(DeployError, match=r"\.mpy version mismatch.*v5\.0.*v6\."):
        d.deploy()
    assert not any((micropython_device.flash).iterdir())   # type: ignore[attr-defined]


def test_deploy_refuses_firmware_failing_the_subset_check(micropython_device: PtyRelay,
                                                          tmp_path) -> None:
    import shutil

    from bridge.serial.deploy import FIRMWARE_DIR
    fw = tmp_path / "fw"      # a copy of firmware_logic: the thesis is taken from it
    shutil.copytree(FIRMWARE_DIR, fw, ignore=shutil.ignore_patterns("__pycache__"))
    (fw / "behaviours" / "thesis" / "robot.py").write_text((fw / "behaviours" / "thesis" / "robot.py").read_text()
                                 + "\n\ndef bad():\n    print('x', 1.5)\n")
    with pytest.raises(DeployError, match=r"(?s)subset check.*robot.py:\d+: FW-PRINT"):
        Deployer(micropython_device.path, firmware_dir=fw).deploy()
    assert not any((micropython_device.flash).iterdir())   # type: ignore[attr-defined]


def test_micropython_robot_touches_and_host_journals_it(micropython_device: PtyRelay) -> None:
    deploy_and_start(micropython_device)
    m = Mission(micropython_device)
    try:
        m.run(acked)
        robot = m.halt_and_inspect()
    finally:
        m.close()
    check_outcome(m, robot)
    assert m.engine.world.owner[m.engine.world.idx(m.journal[0].sx, m.journal[0].sy)] == 1


def test_the_whole_board_tick_allocates_nothing_under_heap_lock(
        micropython_device: PtyRelay) -> None:
    """Not only the FSM: the board's tick (TetherHal framing, the serial port
    wrapper, sensing round trips, the touch report, its ACK) runs under
    micropython.heap_lock() after a 20-tick warm-up (HEAP_CHECK), through
    the touch, its journalling and its ACK; not one tick tries to allocate."""
    deploy_and_start(micropython_device, HEAP_CHECK=20)
    fault = micropython_device.flash / "heap_fault.txt"    # type: ignore[attr-defined]
    m = Mission(micropython_device)
    try:
        m.run(lambda m: acked(m) or fault.exists())
        assert not fault.exists(), fault.read_text()       # where a tick allocated
        robot = m.halt_and_inspect()
    finally:
        m.close()
    out = Deployer(micropython_device.path).exec(
        "import main; g = main.LAST['guard']; print('checked', g.checked); "
        "print('faults', g.faults)")
    heap = {k: int(v) for k, v in re.findall(r"^(checked|faults) (-?\d+)\s*$", out, re.M)}
    assert heap["faults"] == 0, out
    check_outcome(m, robot)
    assert heap["checked"] > 80 and heap["checked"] == robot["ticks"] - 20, (heap, robot)


def test_micropython_robot_survives_garbage_truncation_and_a_vanishing_port(
        micropython_device: PtyRelay) -> None:
    dev = micropython_device
    deploy_and_start(dev)
    m = Mission(dev)
    t0 = time.monotonic()
    state = {"gone": 0.0, "vanished": 0, "next": {"host": 0.3, "child": 0.5, "cut": 0.7}}
    cut = {"left": 0}

    def truncate_some(data: bytes) -> bytes:
        # when armed, drop the tail of one chunk the robot sends (a truncated frame)
        if cut["left"] > 0:
            cut["left"] -= 1
            return data[: max(1, len(data) // 2)]
        return data

    dev.to_host_filter = truncate_some

    def faults(mm: Mission) -> None:
        t = time.monotonic() - t0
        nxt = state["next"]
        if t > nxt["host"]:                  # line noise toward the host
            dev.inject_to_host(b"\x13\x37garbage\xff\x00\x05\x01")
            nxt["host"] = t + 0.3
        if t > nxt["child"]:                 # line noise toward the robot
            dev.inject_to_child(b"\xde\xad\x00\x02\x03junk")
            nxt["child"] = t + 0.5
        if t > nxt["cut"]:                   # one truncated reply
            cut["left"] = 1
            nxt["cut"] = t + 0.7
        if not state["vanished"] and t > 1.0:   # unplugged for half a second
            dev.vanish()
            state["vanished"] = 1
            state["gone"] = time.monotonic()
        if state["gone"] and time.monotonic() - state["gone"] > 0.5:
            dev.come_back()
            state["gone"] = 0.0

    try:
        m.run(lambda mm: acked(mm) and state["vanished"] and not state["gone"],
              fault=faults)
        dev.to_host_filter = None
        robot = m.halt_and_inspect()
    finally:
        m.close()
    check_outcome(m, robot)
    bad = m.serial.bad_frames()
    assert bad.get("disconnect", 0) >= 1, bad
    assert sum(v for k, v in bad.items() if k not in ("disconnect", "send_dropped")) > 0, bad


def test_deploy_another_behaviour_and_the_board_builds_it(micropython_device: PtyRelay,
                                                          capsys: pytest.CaptureFixture[str]
                                                          ) -> None:
    """deploy --behaviour aggregate copies that behaviour (not the thesis's FSM)
    as the package behaviour/ and writes its robot_args into robot_config.py
    (its own parameter applied with --set); on the device, main.build imports
    it and builds the aggregation FSM, and the runtime declares its messages."""
    rc = cli_main(["deploy", "--port", micropython_device.path, "--behaviour", "aggregate",
                   "--set", "robotVisionSpan=30", "--config", "NODE=2"])
    out, err = capsys.readouterr()
    assert rc == 0, out + err
    flash = micropython_device.flash   # type: ignore[attr-defined]
    assert (flash / "behaviour/robot.mpy").is_file()
    assert not (flash / "behaviour/coordinator.mpy").exists()
    config = (flash / "robot_config.py").read_text()
    assert "BEHAVIOUR = 'aggregate'" in config and "ARGS = (2, 1, 1, 30, 2, 100)" in config
    assert "imported aggregate on the device and built its robot (Robot, 6 arguments" in out
    text = Deployer(micropython_device.path).exec(
        "import main\n"
        "from firmware_logic import messages\n"
        "r, s = main.build(main.config())\n"
        "messages.activate(s.MESSAGES)\n"
        "print('built', r.node, r.span, s.STATES[s.STATES.index('halt')], messages.dlc(s.LEAVE))\n")
    assert "built 2 30 halt 5" in text, text


def test_deploy_a_folder_outside_the_repo_and_the_board_imports_it(
        micropython_device: PtyRelay, tmp_path: Path,
        capsys: pytest.CaptureFixture[str]) -> None:
    """A behaviour made by the scaffold in a folder outside the repository,
    with a state only its own down message reaches and a module of its own
    read by relative import (tests/test_behaviour_folder.py): deploy copies
    it as the package behaviour/ (that module too, its coordinator not),
    writes its robot_args, and verifies by importing it on the board; the
    board's runtime then builds it and obeys its own NUDGE."""
    from tests.test_behaviour_folder import scaffold, with_down_only_state
    (tmp_path / "mine").mkdir()
    folder = scaffold(tmp_path / "mine", "nudger")
    with_down_only_state(folder)
    rc = cli_main(["deploy", "--port", micropython_device.path, "--behaviour", str(folder),
                   "--set", "robotVisionSpan=20", "--config", "NODE=5"])
    out, err = capsys.readouterr()
    assert rc == 0, out + err
    flash = micropython_device.flash   # type: ignore[attr-defined]
    own = sorted(p.name for p in (flash / "behaviour").iterdir())
    assert own == ["__init__.mpy", "moves.mpy", "robot.mpy", "spec.mpy"]
    assert "ARGS = (5, 1, 1, 20, 2, 100)" in (flash / "robot_config.py").read_text()
    assert "imported nudger on the device and built its robot (Robot, 6 arguments, " \
        "state search)" in out
    text = Deployer(micropython_device.path).exec(
        "import main\n"
        "r, s = main.build(main.config())\n"
        "class Hal:\n"
        "    q = [s.NUDGE]\n"
        "    def recv(self, buf):\n"
        "        return self.q.pop() if self.q else 0\n"
        "    def beacon(self, on):\n"
        "        pass\n"
        "    def __getattr__(self, name):\n"
        "        return lambda *a: 0\n"
        "r.state = s.STAY\n"
        "r.step(Hal())\n"
        "print('after nudge', s.STATES[r.state], r.flee)\n")
    assert "after nudge flee 4" in text, text


def test_deploy_refuses_a_behaviour_the_board_cannot_import(
        micropython_device: PtyRelay, tmp_path: Path) -> None:
    """Copied and hashed is not enough: a robot.py importing a module the
    board does not have (here the host's roster, not deployed) fails the
    import on the device, and the deploy says so."""
    from tests.test_behaviour_folder import edit, scaffold
    (tmp_path / "mine").mkdir()
    folder = scaffold(tmp_path / "mine", "hosty")
    edit(folder / "robot.py", "from firmware_logic.rng import Rng\n",
         "from firmware_logic.rng import Rng\nfrom firmware_logic import roster  # noqa: F401\n")
    with pytest.raises(DeployError, match=r"could not import the behaviour 'hosty'.*roster"):
        Deployer(micropython_device.path, behaviour=str(folder)).deploy({"NODE": 1})
