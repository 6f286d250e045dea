"""Every command refuses bad input the same way: exit 2, no traceback, and
one line on stderr naming what was wrong, before any port opens or any run
starts. One row per bad input a user has been seen to type.

Runs in-process through `bridge.cli.main`, so a row costs milliseconds; the
argv's "{T}" is a folder of bad files made once for the module.
"""

from __future__ import annotations

import contextlib
import io
import os
import signal

import pytest

from bridge import cli

FIXTURES = {
    "empty.blf": b"", "empty.asc": b"", "empty.log": b"", "empty.csv": b"", "empty.trc": b"",
    "random.blf": bytes(range(256)) * 12, "random.asc": bytes(range(255, -1, -1)) * 12,
    "random.log.gz": bytes(range(7, 250)),
    "text.log": b"hello world\nnot a can log\n", "rec.xyz": b"abc",
    "bad.toml": b"agents = [\n", "badkey.toml": b"colour = 3\n",
    "badtype.toml": b'agents = "many"\n', "bin.toml": bytes([0xff, 0xfe, 0x00, 0x81]) * 50,
    "journal.sqlite": b"this is not sqlite at all" * 100, "plainfile": b"x",
    "fewkeys.toml": b'[keys]\n1 = "' + b"1" * 32 + b'"\n',
    "zerokey.toml": b'[keys]\n1 = "' + b"0" * 32 + b'"\n',
    "dupkeys.toml": b'[keys]\n1 = "' + b"1" * 32 + b'"\n01 = "' + b"2" * 32 + b'"\n',
    "supkey.toml": '[keys]\n"\u00b2" = "'.encode() + b"1" * 32 + b'"\n',
    "fvnull.toml": b"[keys]\n" + b"".join(b'%d = "%032x"\n' % (n, n) for n in range(1, 21)),
    "fvnull.toml.fv.json": b'{"1": null}',
    "shared.toml": b'[keys]\n1 = "' + b"1" * 32 + b'"\n',
}
# key files are private (`touchswarm keys new` writes them 0600); shared.toml is not
PUBLIC = {"shared.toml"}

ROWS = [
    # run: numbers, scenario keys, scenario files, behaviours, outputs
    (["run", "--seed", "-1"], "--seed -1: outside 0..1000002"),
    (["run", "--seed", "abc"], "argument --seed: invalid int value: 'abc'"),
    (["run", "--seed", "1000003"], "--seed 1000003: outside"),
    (["run", "--robots", "-3"], "agents: -3 is outside the allowed range"),
    (["run", "--robots", "100000"], "agents: 100000 is outside"),
    (["run", "--set", "=3"], "expected KEY=VALUE"),
    (["run", "--set", "agents="], "expected KEY=VALUE"),
    (["run", "--set", "maxTicks=-1"], "maxTicks: -1 is outside"),
    (["run", "--set", "worldSize=2"], "worldSize: 2 is outside"),
    (["run", "--set", "sigRadius=-1"], "sigRadius: -1 is outside"),
    (["run", "--set", "rPower=0"], "rPower: 0 is outside"),
    (["run", "--set", "rPower=nan"], "rPower: nan is outside"),
    (["run", "--set", "rPower=inf"], "rPower: inf is outside"),
    (["run", "--set", "objectWeight=nan"], "objectWeight: nan is outside"),
    (["run", "--set", "visionSpan=400"], "unknown key 'visionSpan'"),
    (["run", "--set", "signalMode=centre"], "signalMode: expected one of patch, netlogo"),
    (["run", "--set", "uphillTies=1"], "uphillTies: expected one of ordered, netlogo"),
    (["run", "--set", "leaderField=on"], "leaderField: expected one of off, netlogo"),
    (["run", "--set", "arrival=1"], "arrival: expected one of within4, netlogo"),
    (["sweep", "--grid", "starts=netlogo,random", "--seeds", "1"],
     "starts: expected one of redraw, netlogo"),
    (["run", "--set", "object=blob"], "object: expected 1-4, 'none' or one of"),
    (["run", "--set", "movementModel=6"], "movementModel: expected one of 'firefly' (1)"),
    (["run", "--set", "agents=1e9"], "agents: 1000000000 is outside"),
    (["run", "--scenario", "{T}/bad.toml"], "bad.toml: not valid TOML"),
    (["run", "--scenario", "{T}/badkey.toml"], "unknown key 'colour'"),
    (["run", "--scenario", "{T}/badtype.toml"], "agents: expected int"),
    (["run", "--scenario", "{T}/bin.toml"], "bin.toml': not UTF-8 text"),
    (["run", "--scenario", "{T}/missing.toml"], "missing.toml': No such file"),
    (["run", "--scenario", "{T}"], "a directory, not a regular file"),
    (["run", "--scenario", ""], "scenario: an empty name"),
    (["run", "--behaviour", "nope"], "behaviour 'nope': not an installed behaviour"),
    (["run", "--behaviour", "{T}"], "has no __init__.py"),
    (["run", "--out", "{T}/plainfile"], "plainfile: is a file; expected a directory"),
    (["run", "--out", "/proc/x"], "--out /proc/x: cannot create this directory"),
    (["run", "--out", ""], "argument --out: an empty path"),
    (["run", "--out", "/dev/null/x"], "/dev/null is a file"),
    (["run", "--record", "{T}/missing/dir/r.blf"], "dir does not exist"),
    (["run", "--record", "{T}/r.blf.gz"], "cannot gzip .blf"),
    (["run", "--record", "{T}/r.xyz"], "r.xyz: unknown recording format"),
    (["run", "--record", "{T}/adir.log", "--link", "can"], "is a directory; expected a file path"),
    (["run", "--trace", "{T}/t.txt"], "--trace {T}/t.txt: unknown trace format '.txt'"),
    (["run", "--trace", "{T}/trace"], "unknown trace format '(no suffix)'"),
    (["run", "--trace", "{T}/missing/t.csv"], "missing does not exist"),
    (["run", "--trace", "{T}/adir.log"], "is a directory; expected a file path"),
    (["run", "--animate", "{T}"], "is a directory; expected a file path such as"),
    (["run", "--trace", ""], "argument --trace: an empty path"),
    (["run", "--animate", "{T}/a.png"], "--animate {T}/a.png: unknown animation format '.png'"),
    (["run", "--animate", "{T}/missing/a.gif"], "missing does not exist"),
    (["run", "--animate", "/proc/a.gif"], "--animate /proc: cannot write in this directory"),
    (["run", "--animate", ""], "argument --animate: an empty path"),
    (["run", "--frame-every", "0", "--animate", "a.gif"], "--frame-every: 0: expected ticks"),
    (["run", "--frame-every", "x", "--animate", "a.gif"], "'x' is not a whole number"),
    (["run", "--frame-every", "3"], "--frame-every 3: only with --animate FILE"),
    (["run", "--link", "udp"], "invalid choice: 'udp'"),
    (["run", "--link", "can", "--robots", "200"], "do not fit the CAN link's node ids"),
    # behaviour scaffolding
    (["behaviour", "new", ""], "behaviour name '': use a lower-case Python identifier"),
    (["behaviour", "new", "../evil"], "behaviour name '../evil'"),
    (["behaviour", "new", "thesis"], "behaviour 'thesis' exists already"),
    (["behaviour", "new", "ok_name", "--into", "{T}/plainfile"], "no such folder"),
    (["behaviour", "new", "ok_name", "--into", ""], "argument --into: an empty path"),
    (["scenarios", "extra"], "unrecognized arguments: extra"),
    # dbc
    (["dbc", "--out", "/proc/x.dbc"], "--out /proc: cannot write in this directory"),
    (["dbc", "--out", "{T}/missing/x.dbc"], "missing does not exist"),
    (["dbc", "--out", "{T}"], "is a directory; expected a file path"),
    (["dbc", "--max-node", "0"], "argument --max-node: 0: expected a node id 1..127"),
    (["dbc", "--max-node", "999"], "999: expected a node id 1..127"),
    (["dbc", "--max-node", "x"], "'x' is not a whole number"),
    (["firmware", "nothing"], "invalid choice: 'nothing'"),
    (["firmware", "check", "--behaviour", "nope"], "behaviour 'nope'"),
    # replay: missing, empty, foreign, unknown, directory
    (["replay", "{T}/missing.blf"], "no such recording"),
    (["replay", "{T}/empty.blf"], "empty.blf is empty (0 bytes)"),
    (["replay", "{T}/empty.asc"], "empty.asc is empty"),
    (["replay", "{T}/empty.log"], "empty.log is empty"),
    (["replay", "{T}/empty.csv"], "empty.csv is empty"),
    (["replay", "{T}/empty.trc"], "empty.trc is empty"),
    (["replay", "{T}/random.blf"], "has no sidecar random.blf.json"),
    (["replay", "{T}/random.asc"], "has no sidecar random.asc.json"),
    (["replay", "{T}/random.log.gz"], "has no sidecar random.log.gz.json"),
    (["replay", "{T}/text.log"], "has no sidecar text.log.json"),
    (["replay", "{T}/rec.xyz"], "rec.xyz: unknown recording format"),
    (["replay", "{T}"], "is a directory; expected a recording file"),
    (["replay", "{T}/adir.log"], "adir.log is a directory"),
    (["replay", ""], "argument FILE: an empty path"),
    # sweep
    (["sweep", "--grid", "sigRadius=3,4", "--seeds", "0"], "--seeds 0: a count must be"),
    (["sweep", "--grid", "sigRadius=3,4", "--seeds", "5-2"], "the range is empty"),
    (["sweep", "--grid", "sigRadius=3,4", "--seeds", "1,1"], "seed 1 is listed twice"),
    (["sweep", "--grid", "sigRadius=3,4", "--seeds", "a"], "--seeds 'a': expected a count"),
    (["sweep", "--grid", "sigRadius=3,4", "--seeds", "1-2000000"], "seed 1000003 is outside"),
    (["sweep", "--grid", "sigRadius=3,4", "--chunk", "0"], "--chunk 0: expected at least 1"),
    (["sweep", "--grid", "sigRadius=3,4", "--executor", "bogus"], "expected processes[:N]"),
    (["sweep", "--grid", "sigRadius=3,4", "--executor", "processes:0"], "N >= 1 worker"),
    (["sweep", "--grid", "sigRadius=3,4", "--out", "{T}/plainfile"], "is a file; expected a dir"),
    (["sweep", "--grid", "sigRadius=3,4", "--out", ""], "argument --out: an empty path"),
    (["sweep", "--grid", "sigRadius=3,4", "--engine", "batch"],       # retired: one line
     "invalid choice: 'batch' (choose from 'auto', 'soa', 'reference')"),
    (["sweep", "--grid", "nokey=1,2"], "--grid nokey: unknown scenario key"),
    (["sweep", "--grid", "sigRadius"], "expected KEY=V1,V2,..."),
    (["sweep", "--grid", "sigRadius=1,1"], "value 1 is listed twice"),
    (["sweep", "--grid", "sigRadius=99"], "sigRadius: 99 is outside"),
    (["sweep", "--grid", "sigRadius=1", "--grid", "sigRadius=2"], "--grid sigRadius given twice"),
    (["sweep", "--grid", "sigRadius=3", "--set", "sigRadius=4"], "both given"),
    (["sweep", "--engine", "warp"], "invalid choice: 'warp'"),
    (["sweep", "--grid", "agents=0,5"], "agents: 0 is outside"),
    (["sweep", "--thesis", "--grid", "sigRadius=3"], "--thesis runs its own grid"),
    # host: links, devices, numbers, journals -- all refused before a port opens
    (["host"], "give --bus URL and/or --serial PORT"),
    (["host", "--bus", "nope://x"], "unknown link 'nope://x'"),
    (["host", "--bus", "virtual://x"], "virtual bus does not cross processes"),
    (["host", "--bus", "slcan://{T}/missing"], "no such device"),
    (["host", "--serial", "{T}/missing"], "--serial {T}/missing: no such device"),
    (["host", "--bus", "slcan:///dev/null", "--tick-ms", "0"], "--tick-ms: 0: expected milliseconds > 0"),
    (["host", "--bus", "slcan:///dev/null", "--tick-ms", "nan"], "expected a finite number"),
    (["host", "--bus", "slcan:///dev/null", "--max-ticks", "-1"], "--max-ticks: -1: expected ticks"),
    (["host", "--bus", "slcan:///dev/null", "--bus-timeout", "-1"], "--bus-timeout: -1"),
    (["host", "--bus", "slcan:///dev/null", "--node-timeout", "-1"], "--node-timeout: -1"),
    (["host", "--bus", "slcan:///dev/null", "--serial-baud", "-1"], "--serial-baud: -1"),
    (["host", "--bus", "slcan:///dev/null?bitrate=abc"], "bitrate='abc' is not an integer"),
    (["host", "--resume", "{T}/journal.sqlite", "--bus", "slcan:///dev/null"],
     "journal.sqlite: file is not a database"),
    (["host", "--resume", "{T}/missing.sqlite", "--bus", "slcan:///dev/null"], "no such journal"),
    (["host", "--journal", "{T}/missing/j.sqlite", "--bus", "slcan:///dev/null"],
     "cannot open journal"),
    (["host", "--journal", "", "--bus", "slcan:///dev/null"], "argument --journal: an empty path"),
    # robots
    (["robots"], "the following arguments are required: --bus"),
    (["robots", "--bus", "virtual://x"], "virtual bus does not cross processes"),
    (["robots", "--bus", "slcan:///dev/null", "--loss", "2"], "--loss: 2: expected a share"),
    (["robots", "--bus", "slcan:///dev/null", "--loss", "-0.1"], "expected a share 0 <= p < 1"),
    (["robots", "--bus", "slcan:///dev/null", "--dup", "x"], "'x' is not a number"),
    (["robots", "--bus", "slcan:///dev/null", "--reorder", "0"], "expected a window of frames"),
    (["robots", "--bus", "slcan:///dev/null", "--linger-ms", "-1"], "--linger-ms: -1"),
    (["robots", "--bus", "slcan:///dev/null", "--robots", "200"], "do not fit the CAN link"),
    (["robots", "--bus", "slcan:///dev/null", "--tick-ms", "inf"], "expected a finite number"),
    # mission
    (["mission"], "required: --body"),
    (["mission", "--body", "1"], "--body '1': expected NODE=URL"),
    (["mission", "--body", "0=sim://"], "node 0 is not a robot of the scenario"),
    (["mission", "--body", "99=sim://"], "node 99 is not a robot"),
    (["mission", "--body", "1=ftp://x"], "unknown kind 'ftp'"),
    (["mission", "--body", "1=khepera://{T}/missing"], "no such device"),
    (["mission", "--body", "1=gogo:///dev/null?baud=x"], "baud='x' is not an integer"),
    (["mission", "--body", "1=sim://", "--body", "1=sim://"], "given twice"),
    (["mission", "--body", "x=sim://"], "node 'x' is not a number"),
    (["mission", "--body", "1=sim://", "--tick-ms", "-1"], "--tick-ms: -1: expected milliseconds"),
    (["mission", "--body", "1=sim://", "--max-ticks", "0"], "--max-ticks: 0"),
    # deploy
    (["deploy"], "required: --port"),
    (["deploy", "--port", "{T}/missing"], "--port {T}/missing: no such device"),
    (["deploy", "--port", "/dev/null", "--config", "NODE=x"], "the value must be an integer"),
    (["deploy", "--port", "/dev/null", "--config", "NODE=0"], "--config NODE=0: expected 1..127"),
    (["deploy", "--port", "/dev/null", "--config", "SEED=-1"], "--config SEED=-1: expected"),
    (["deploy", "--port", "/dev/null", "--config", "COLOUR=1"], "expected KEY=N with KEY one of"),
    (["deploy", "--port", "/dev/null", "--mpy-cross", "{T}/missing"], "--mpy-cross {T}/missing: no such file"),
    (["deploy", "--port", "/dev/null", "--mpremote", "{T}/plainfile"], "not an executable program"),
    # keys (authenticated host commands)
    (["keys", "new", "--out", "{T}/plainfile"], "exists already"),
    (["keys", "new", "--nodes", "0", "--out", "k.toml"], "--nodes: 0: expected a robot count"),
    (["keys", "new", "--nodes", "200", "--out", "k.toml"], "node ids 1..127"),
    (["keys", "new", "--out", "{T}/missing/k.toml"], "missing does not exist"),
    (["host", "--bus", "slcan:///dev/null", "--keys", "{T}/missing.toml"],
     "--keys: key file '{T}/missing.toml': No such file"),
    (["host", "--bus", "slcan:///dev/null", "--keys", "{T}/bad.toml"], "not valid TOML"),
    (["host", "--bus", "slcan:///dev/null", "--keys", "{T}/badkey.toml"], "no [keys] table"),
    (["robots", "--bus", "slcan:///dev/null", "--keys", "{T}/bin.toml"], "not UTF-8 text"),
    (["robots", "--bus", "slcan:///dev/null", "--keys", "{T}/fewkeys.toml"],
     "no key for node 2 (the scenario has 20 robots, the file 1 keys)"),
    (["host", "--bus", "slcan:///dev/null", "--keys", "{T}/zerokey.toml"],
     "node 1: an all-zero key is no secret"),
    (["host", "--bus", "slcan:///dev/null", "--keys", "{T}/dupkeys.toml"],
     "node 1 is given twice ('1' and '01')"),
    (["robots", "--bus", "slcan:///dev/null", "--keys", "{T}/supkey.toml"],
     "expected a node id 1..127"),
    (["host", "--bus", "slcan:///dev/null", "--keys", "{T}/shared.toml"],
     "mode 0644 lets others read it; keys must be private: chmod 600"),
    (["host", "--bus", "slcan:///dev/null", "--keys", "/dev/zero"], "not a regular file"),
    (["robots", "--bus", "slcan:///dev/null", "--keys", "{T}/fifo.toml"], "not a regular file"),
    (["host", "--bus", "slcan:///dev/null", "--keys", "{T}/fvnull.toml"],
     "node 1: counter null; expected an integer 0..4294967295"),
    # top level
    (["nosuchcommand"], "invalid choice: 'nosuchcommand'"),
    (["-v", "run", "--seed"], "argument --seed: expected one argument"),
]


@pytest.fixture(scope="module")
def bad_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bad")
    for name, data in FIXTURES.items():
        (folder / name).write_bytes(data)
        (folder / name).chmod(0o644 if name in PUBLIC else 0o600)
    os.mkfifo(folder / "fifo.toml")     # reading it would wait for a writer for ever
    (folder / "adir.log").mkdir()  # a directory named like a recording
    return str(folder)


class _Hung(Exception):
    pass


def _alarm(signum, frame):
    raise _Hung()


@pytest.mark.parametrize("argv, needle", ROWS, ids=[" ".join(a) or "''" for a, _ in ROWS])
def test_bad_input_is_refused_in_one_line_with_exit_2(argv, needle, bad_files, tmp_path,
                                                      monkeypatch):
    monkeypatch.chdir(tmp_path)  # anything a refused command wrongly writes lands here
    argv = [a.replace("{T}", bad_files) for a in argv]
    needle = needle.replace("{T}", bad_files)
    err = io.StringIO()
    # a hang guard only: every row is refused before any work, in milliseconds
    old = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(60)
    try:
        with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
            try:
                rc = cli.main(argv)
            except SystemExit as exc:  # argparse refuses by exiting
                rc = exc.code
    except _Hung:
        pytest.fail(f"touchswarm {' '.join(argv)} hung instead of refusing")
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)
    text = err.getvalue()
    lines = [line for line in text.splitlines() if line.strip()]
    assert rc == 2, text
    assert "Traceback" not in text
    assert lines, "refused without saying why"
    # argparse prints the usage block before its one error line; ours print one line
    assert needle in lines[-1], lines[-1]
    assert lines[-1].startswith("touchswarm"), lines[-1]
    assert os.listdir(tmp_path) == [], "a refused command left files behind"
