"""Record a run (python-can formats), replay it, detect divergence, decode with cantools."""

import json
import re
import subprocess
import sys
from pathlib import Path

import can
import pytest

from bridge.cli import main
from bridge.record.replay import replay
from firmware_logic import messages as msg

ROOT = Path(__file__).resolve().parents[1]
SMALL = ["--robots", "8", "--set", "objectWeight=2", "--seed", "3"]


@pytest.mark.parametrize("suffix", [".blf", ".asc", ".log", ".log.gz"])
def test_record_then_replay_is_identical(tmp_path, suffix, capsys):
    f = tmp_path / ("run" + suffix)
    assert main(["run", *SMALL, "--record", str(f), "--json"]) == 0
    run = json.loads(capsys.readouterr().out)
    meta = json.loads(Path(str(f) + ".json").read_text())
    assert meta["summary"] == run and meta["seed"] == 3
    kinds = {msg.split_id(m.arbitration_id)[0] for m in can.LogReader(str(f))}
    assert {msg.SENSOR, msg.ACTION, msg.HELLO, msg.TOUCH, msg.ACK, msg.TRANSPORT,
            msg.HALT} <= kinds
    assert main(["replay", str(f)]) == 0
    out = capsys.readouterr().out
    assert "0 divergences" in out and "DIVERGED" not in out
    s = replay(f)
    assert s["divergences"] == 0 and s["ticks"] == run["ticks"]
    assert s["touches"] == len(run["touches"]) and s["delivered_tick"] == run["home_tick"]


def test_can_link_recording_equals_inproc_recording(tmp_path):
    a, b = tmp_path / "a.log", tmp_path / "b.log"
    assert main(["run", *SMALL, "--record", str(a), "--json"]) == 0
    assert main(["run", *SMALL, "--link", "can", "--record", str(b), "--json"]) == 0
    assert a.read_bytes() == b.read_bytes()


def _tamper(src: Path, dst: Path, pick) -> None:
    lines = src.read_text().splitlines(keepends=True)
    i = pick(lines)
    ts, ch, frame = lines[i].split()[:3]
    ident, data = frame.split("#")
    b = bytearray.fromhex(data)
    b[-2] ^= 0x01          # flip a bit of the last field
    lines[i] = "%s %s %s#%s R\n" % (ts, ch, ident, b.hex().upper())
    dst.write_text("".join(lines))
    Path(str(dst) + ".json").write_text(Path(str(src) + ".json").read_text())


def test_replay_reports_each_divergence(tmp_path, capsys):
    f = tmp_path / "run.log"
    assert main(["run", *SMALL, "--record", str(f), "--json"]) == 0
    capsys.readouterr()
    # a recorded decision changed: an ACTION frame of robot 2 (forward step)
    bad = tmp_path / "act.log"
    _tamper(f, bad, lambda ls: next(i for i, l in enumerate(ls) if " 582#" in l))
    assert main(["replay", str(bad)]) == 1
    out = capsys.readouterr().out
    assert "DIVERGED tick" in out and "robot 2: actions" in out
    # a host command changed: the first TRANSPORT
    bad2 = tmp_path / "host.log"
    _tamper(f, bad2, lambda ls: next(i for i, l in enumerate(ls)
                                    if re.match(r"1[0-7][0-9A-F]#", l.split()[2])))
    assert main(["replay", str(bad2), "--json"]) == 1
    s = json.loads(capsys.readouterr().out)
    assert s["divergences"] >= 1 and "host: sent" in s["differences"][0]


def test_replay_realtime_and_missing_sidecar(tmp_path, capsys):
    f = tmp_path / "short.asc"
    main(["run", *SMALL, "--set", "maxTicks=15", "--record", str(f), "--json"])
    assert main(["replay", "--realtime", str(f)]) == 0
    Path(str(f) + ".json").unlink()
    assert main(["replay", str(f)]) == 2
    assert "sidecar" in capsys.readouterr().err
    bare = tmp_path / "bare.log"          # bus traffic only, no capture frames
    with can.Logger(str(bare)) as w:
        w.on_message_received(can.Message(arbitration_id=msg.can_id(msg.HELLO, 1),
                                          data=b"\x01\x64\x00\x01", is_extended_id=False))
    Path(str(bare) + ".json").write_text('{"scenario": {}, "seed": 1}')
    assert main(["replay", str(bare)]) == 2
    assert "no SENSOR/ACTION capture frames" in capsys.readouterr().err
    assert main(["run", *SMALL, "--record", str(tmp_path / "x.txt")]) == 2


def test_cantools_decodes_a_recording(tmp_path):
    f = tmp_path / "run.log"
    main(["run", *SMALL, "--set", "maxTicks=30", "--record", str(f), "--json"])
    exe = Path(sys.executable).with_name("cantools")
    out = subprocess.run([str(exe), "decode", str(ROOT / "docs" / "touchswarm.dbc")],
                         input=f.read_text(), capture_output=True, text=True, check=True).stdout
    assert "SENSOR_1(" in out and "HELLO_8(" in out and "ACK_1(" in out
    # physical values and names, not raw codes (issue: x: 598 for 2.34 patches)
    assert "query: recv" in out and "model: firefly" in out and "Unknown" not in out
    assert "power: 1.0 power" in out and "action: forward" in out


def test_python_can_tools_open_a_recording(tmp_path):
    f = tmp_path / "run.blf"
    main(["run", *SMALL, "--set", "maxTicks=40", "--record", str(f), "--json"])
    conv = tmp_path / "conv.asc"
    subprocess.run([sys.executable, "-m", "can.logconvert", str(f), str(conv)], check=True,
                   capture_output=True)
    Path(str(conv) + ".json").write_text(Path(str(f) + ".json").read_text())
    assert replay(conv)["divergences"] == 0
    assert replay(conv)["frames"] == replay(f)["frames"]
    subprocess.run([sys.executable, "-m", "can.player", "-i", "virtual", "-c", "player-test",
                    "--ignore-timestamps", str(f)], check=True, capture_output=True, timeout=60)


def test_an_aggregate_recording_replays_as_aggregate(tmp_path, capsys):
    # issue 9: replay builds the behaviour the run was recorded with
    f = tmp_path / "agg.blf"
    assert main(["run", *SMALL, "--set", "behaviour=aggregate", "--link", "can",
                 "--record", str(f), "--json"]) == 0
    run = json.loads(capsys.readouterr().out)
    meta = json.loads(Path(str(f) + ".json").read_text())
    assert meta["behaviour"] == "aggregate" == meta["scenario"]["behaviour"]
    assert main(["replay", str(f)]) == 0
    assert "0 divergences" in capsys.readouterr().out
    s = replay(f)
    assert s["divergences"] == 0 and s["ticks"] == run["ticks"]
    assert s["delivered_tick"] == run["home_tick"]
    # the same frames replayed on the thesis firmware diverge: the choice matters
    meta["scenario"]["behaviour"] = meta["behaviour"] = "thesis"
    Path(str(f) + ".json").write_text(json.dumps(meta))
    assert replay(f)["divergences"] > 0


def test_a_recording_without_behaviour_replays_as_thesis(tmp_path, capsys):
    # recordings made before the seam carry no behaviour key anywhere
    f = tmp_path / "old.log"
    assert main(["run", *SMALL, "--record", str(f), "--json"]) == 0
    capsys.readouterr()
    mp = Path(str(f) + ".json")
    meta = json.loads(mp.read_text())
    del meta["behaviour"], meta["scenario"]["behaviour"], meta["scenario"]["quorum"]
    mp.write_text(json.dumps(meta))
    assert replay(f)["divergences"] == 0
    # a hand-edited sidecar whose two behaviour names disagree is refused in one line
    meta["behaviour"] = "aggregate"
    mp.write_text(json.dumps(meta))
    assert main(["replay", str(f)]) == 2
    err = capsys.readouterr().err.strip()
    assert "behaviour 'aggregate'" in err and "'thesis'" in err and "\n" not in err
    meta["behaviour"] = meta["scenario"]["behaviour"] = "nosuch"
    mp.write_text(json.dumps(meta))
    assert main(["replay", str(f)]) == 2
    assert "not an installed behaviour" in capsys.readouterr().err
