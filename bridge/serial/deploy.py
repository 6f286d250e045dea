"""Deploy the robot firmware to a MicroPython board over serial.

Steps (each failure is a DeployError naming what was wrong):

1. subset check (bridge/firmware/subset_check.py) of every firmware module
   the board runs; any violation refuses the deploy;
2. compile each module with mpy-cross;
3. ask the device its .mpy version (sys.implementation._mpy) and refuse when
   it differs from what mpy-cross emits;
4. copy with mpremote (`fs mkdir`, `fs cp`), the board's main.py as source
   and, if given, a robot_config.py;
5. read back every file's sha256 on the device (`fs sha256sum`) and compare.

mpremote is run as a subprocess with `resume` (no soft reset: the unix port
cannot do one, and a board keeps running what it runs until main.py is
started). PORT is a device path or any pyserial URL.
"""

from __future__ import annotations

import hashlib
import logging
import os
import re
import shutil
import subprocess
import sys
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

from bridge.errors import BridgeError

log = logging.getLogger(__name__)

ROOT = Path(__file__).resolve().parents[2]
FIRMWARE_DIR = ROOT / "firmware_logic"
BOARD_MAIN = Path(__file__).resolve().parent / "board_main.py"
# what the board runs besides the behaviour: helpers, schema, framing, runtime
CORE_MODULES = ("__init__", "fixedpoint", "rng", "messages", "hal", "framing", "board",
                "behaviours/__init__")
# the behaviour deployed unless told otherwise (its package's modules follow)
BEHAVIOUR_MODULES = ("behaviours/thesis/__init__", "behaviours/thesis/spec",
                     "behaviours/thesis/robot")
MODULES = CORE_MODULES + BEHAVIOUR_MODULES
HOST_SIDE = ("coordinator",)   # a behaviour's modules the board does not run


def behaviour_modules(name: str, firmware_dir: Path = FIRMWARE_DIR) -> tuple[str, ...]:
    """The board-side modules of a built-in behaviour, relative to firmware_dir;
    DeployError for one that lives elsewhere (deploy copies firmware_logic only)."""
    from firmware_logic import registry
    try:
        b = registry.load(name)
    except registry.BehaviourError as err:
        raise DeployError(str(err)) from None
    folder = b.folder
    if folder.parent != (Path(firmware_dir) / "behaviours").resolve():
        raise DeployError("behaviour %r lives in %s, outside firmware_logic/behaviours/; "
                          "deploy copies built-in behaviours only" % (name, folder))
    return tuple("behaviours/%s/%s" % (folder.name, p.stem) for p in b.modules()
                 if p.stem not in HOST_SIDE)
REMOTE_PKG = "firmware_logic"
TIMEOUT_S = 60.0
RAW_REPL_TRIES = 3
RAW_REPL_FAILURE = "could not enter raw repl"   # mpremote's words (transport_serial.py)


class DeployError(BridgeError):
    """The firmware was not deployed; the message says why."""


@dataclass
class DeployedFile:
    remote: str
    size: int
    sha256: str


@dataclass
class DeployReport:
    port: str
    mpy_version: str
    files: list[DeployedFile] = field(default_factory=list)
    # a deploy without config leaves the device's robot_config.py in place:
    # its text, so the caller can say which configuration the robot keeps
    kept_config: str | None = None

    @property
    def total_bytes(self) -> int:
        return sum(f.size for f in self.files)


def _tool(name: str, given: str | None) -> str:
    if given:
        return given
    here = Path(sys.executable).parent / name
    if here.exists():
        return str(here)
    found = shutil.which(name)
    if not found:
        raise DeployError("%s not found: install it (pip install %s) or pass --%s PATH"
                          % (name, name, name))
    return found


def mpy_header_version(data: bytes) -> tuple[int, int, int]:
    """(version, sub-version, native arch; 0 = bytecode only) of an .mpy file."""
    if len(data) < 4 or data[0:1] != b"M":
        raise DeployError("not an .mpy file (no 'M' header)")
    return data[1], data[2] & 3, data[2] >> 2


def mpy_compatible(device: tuple[int, int], file: tuple[int, int, int]) -> bool:
    """MicroPython loads bytecode-only .mpy files of its own version; the
    sub-version matters only for files holding native code."""
    if device[0] != file[0]:
        return False
    return file[2] == 0 or device[1] == file[1]


def device_mpy_version(sys_mpy: int) -> tuple[int, int]:
    """(version, sub-version) from sys.implementation._mpy."""
    return sys_mpy & 0xFF, (sys_mpy >> 8) & 3


def subset_violations(paths: list[Path]) -> list[str]:
    try:
        from bridge.firmware.subset_check import check_paths
    except ImportError as err:
        raise DeployError("the subset checker (bridge.firmware.subset_check) is missing: %s"
                          % err) from err
    return [str(v) for v in check_paths([str(p) for p in paths])]


class Deployer:
    def __init__(self, port: str, mpy_cross: str | None = None, mpremote: str | None = None,
                 firmware_dir: Path = FIRMWARE_DIR, timeout: float = TIMEOUT_S,
                 behaviour: str = "thesis") -> None:
        self.port = port
        self.behaviour = behaviour
        self.modules = CORE_MODULES + (BEHAVIOUR_MODULES if behaviour == "thesis"
                                       else behaviour_modules(behaviour, firmware_dir))
        self.mpy_cross = _tool("mpy-cross", mpy_cross)
        self.mpremote = _tool("mpremote", mpremote)
        self.firmware_dir = Path(firmware_dir)
        self.timeout = timeout

    # -- subprocesses ----------------------------------------------------------

    def _mpremote(self, *args: str) -> str:
        # A board that is slow to answer Ctrl-C/Ctrl-A (busy, line noise, a loaded host
        # running the unix port) makes mpremote give up before any code ran, so a
        # retry cannot run anything twice; other failures are not retried.
        for attempt in range(1, RAW_REPL_TRIES + 1):
            try:
                return self._mpremote_once(*args)
            except DeployError as err:
                if RAW_REPL_FAILURE not in str(err) or attempt == RAW_REPL_TRIES:
                    raise
                log.warning("%s; retrying (%d of %d)", err, attempt + 1, RAW_REPL_TRIES)
        raise AssertionError("unreachable")

    def _mpremote_once(self, *args: str) -> str:
        cmd = [self.mpremote, "connect", "port:" + self.port, "resume", *args]
        log.debug("running %s", " ".join(cmd))
        try:
            r = subprocess.run(cmd, capture_output=True, text=True, timeout=self.timeout)
        except subprocess.TimeoutExpired as err:
            raise DeployError("mpremote on %s did not finish within %.0f s (is the board "
                              "busy running firmware? stop it and retry)"
                              % (self.port, self.timeout)) from err
        if r.returncode != 0:
            msg = (r.stderr.strip() or r.stdout.strip()).splitlines()
            raise DeployError("mpremote %s on %s failed: %s"
                              % (args[0], self.port, msg[-1] if msg else "exit %d" % r.returncode))
        return r.stdout

    def exec(self, code: str) -> str:
        return self._mpremote("exec", code)

    def start(self, code: str = "import main; main.main()") -> None:
        """Start the firmware on the device and return at once (mpremote
        exec --no-follow); the serial port is then the firmware's."""
        self._mpremote("exec", "--no-follow", code)

    # -- steps ------------------------------------------------------------------

    def sources(self) -> list[Path]:
        out = []
        for m in self.modules:
            p = self.firmware_dir / (m + ".py")
            if not p.exists():
                raise DeployError("firmware module %s is missing" % p)
            out.append(p)
        return out

    def check(self, sources: list[Path]) -> None:
        bad = subset_violations(sources)
        if bad:
            raise DeployError("firmware fails the subset check, refusing to deploy:\n  "
                              + "\n  ".join(bad))

    def compile(self, sources: list[Path], out: Path) -> list[Path]:
        done = []
        for src in sources:
            dst = out / src.relative_to(self.firmware_dir).with_suffix(".mpy")
            dst.parent.mkdir(parents=True, exist_ok=True)
            r = subprocess.run([self.mpy_cross, "-o", str(dst), str(src)],
                               capture_output=True, text=True, timeout=self.timeout)
            if r.returncode != 0:
                raise DeployError("mpy-cross failed on %s: %s" % (src, r.stderr.strip()))
            done.append(dst)
        return done

    def device_version(self) -> tuple[int, int]:
        text = self.exec("import sys; print(sys.implementation._mpy)")
        m = re.search(r"^(\d+)\s*$", text, re.M)
        if not m:
            raise DeployError("the device on %s did not report its .mpy version "
                              "(is it MicroPython? got %r)" % (self.port, text.strip()[:80]))
        return device_mpy_version(int(m.group(1)))

    def deploy(self, config: dict[str, int | str] | None = None) -> DeployReport:
        sources = self.sources()
        self.check(sources)
        with tempfile.TemporaryDirectory(prefix="touchswarm-deploy-") as tmp:
            stage = Path(tmp)
            compiled = self.compile(sources, stage)
            want = mpy_header_version(compiled[0].read_bytes())
            have = self.device_version()
            if not mpy_compatible(have, want):
                raise DeployError(
                    ".mpy version mismatch: the device on %s loads .mpy v%d.%d, mpy-cross "
                    "emits v%d.%d; install the mpy-cross release matching the board's "
                    "MicroPython, or pass --mpy-cross PATH"
                    % (self.port, have[0], have[1], want[0], want[1]))
            files: list[tuple[Path, str]] = [
                (p, "%s/%s" % (REMOTE_PKG, p.relative_to(stage).as_posix()))
                for p in compiled]
            main = stage / "main.py"
            shutil.copyfile(BOARD_MAIN, main)
            files.append((main, "main.py"))
            if config:
                cfg = stage / "robot_config.py"
                cfg.write_text("".join("%s = %r\n" % (k, v) for k, v in sorted(config.items())))
                files.append((cfg, "robot_config.py"))
            self._copy(files)
            report = DeployReport(self.port, "%d.%d" % have)
            if not config:
                report.kept_config = self._device_config()
            for local, remote in files:
                data = local.read_bytes()
                report.files.append(DeployedFile(remote, len(data),
                                                 hashlib.sha256(data).hexdigest()))
        self.verify(report)
        return report

    def _device_config(self) -> str | None:
        """The robot_config.py on the device, or None when there is none."""
        try:
            return self._mpremote("fs", "cat", ":robot_config.py")
        except DeployError as err:
            if "no such file" in str(err).lower() or "enoent" in str(err).lower():
                return None
            raise

    def _copy(self, files: list[tuple[Path, str]]) -> None:
        # one mkdir per package folder, then one cp per folder (a few round trips)
        folders: dict[str, list[str]] = {}
        for p, r in files:
            folders.setdefault(r.rpartition("/")[0], []).append(str(p))
        for folder in sorted(f for f in folders if f):
            try:
                self._mpremote("fs", "mkdir", ":" + folder)
            except DeployError as err:
                if "exist" not in str(err).lower():
                    raise
        for folder, local in sorted(folders.items()):
            if folder:
                self._mpremote("fs", "cp", *local, ":%s/" % folder)
            else:
                for p in local:
                    self._mpremote("fs", "cp", p, ":" + Path(p).name)

    def verify(self, report: DeployReport) -> None:
        text = self._mpremote("fs", "sha256sum", *[":" + f.remote for f in report.files])
        got: dict[str, str] = {}
        for line in text.splitlines():
            parts = line.split()
            if len(parts) == 2 and re.fullmatch(r"[0-9a-f]{64}", parts[0]):
                got[parts[1].lstrip(":").lstrip("/")] = parts[0]
            elif len(parts) == 2 and re.fullmatch(r"[0-9a-f]{64}", parts[1]):
                got[parts[0].lstrip(":").lstrip("/")] = parts[1]
        hashes = [h for h in re.findall(r"\b[0-9a-f]{64}\b", text)]
        for i, f in enumerate(report.files):
            h = got.get(f.remote)
            if h is None and len(hashes) == len(report.files):
                h = hashes[i]
            if h != f.sha256:
                raise DeployError("verification failed: %s on the device has sha256 %s, "
                                  "expected %s" % (f.remote, h or "(missing)", f.sha256))


def env_for_tools() -> dict[str, str]:
    env = dict(os.environ)
    env.setdefault("PYTHONUNBUFFERED", "1")
    return env
