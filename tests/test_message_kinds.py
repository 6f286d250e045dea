"""A behaviour's own message kinds: checked against the link's at load (one
line naming the behaviour and its spec.py), per behaviour (two behaviours may
give one free kind different messages without breaking each other), and in
the behaviour's own DBC (`touchswarm dbc --behaviour`)."""

import json
from pathlib import Path

import can
import cantools
import pytest

from bridge.cli import main
from bridge.links import codec, dbc
from firmware_logic import messages as msg
from sim_backend import registry


def scaffold(tmp_path: Path, name: str, spec_edit) -> Path:
    """A behaviour made by `touchswarm behaviour new` outside the repo, its
    spec.py passed through spec_edit."""
    assert main(["behaviour", "new", name, "--into", str(tmp_path)]) == 0
    spec = tmp_path / name / "spec.py"
    text = spec.read_text()
    new = spec_edit(text)
    assert new != text, "the edit did not apply: the test proves nothing"
    spec.write_text(new)
    return tmp_path / name


# the scaffold's kind 7 renamed QUIT, and a down message of kind 8 of its own:
# kind 7 is aggregate's LEAVE, kind 8 the thesis's RELEASE
NUDGE = '''
NUDGE = 8
MESSAGES = MESSAGES + (
    (NUDGE, "NUDGE", DOWN, "host -> robot: move on", (("dx", 1, 1, 1, "patch", -1, 1, ""),)),
)
'''


def own_kinds(text: str) -> str:
    text = text.replace('(LEAVE, "LEAVE", UP,', '(LEAVE, "QUIT", UP,')
    text = text.replace("from firmware_logic.messages import UP",
                        "from firmware_logic.messages import DOWN, UP")
    return text.replace("\nMEASURES = (", NUDGE + "\nMEASURES = (", 1)


def test_a_link_kind_is_refused_at_load_naming_the_behaviour_and_its_file(tmp_path, capsys):
    folder = scaffold(tmp_path, "clash", lambda t: t.replace("LEAVE = 7 ", "LEAVE = 4 "))
    with pytest.raises(registry.BehaviourError) as err:
        registry.load(folder)
    text = str(err.value)
    assert "\n" not in text
    assert str(folder / "spec.py") in text and "clash" in text
    assert "message LEAVE: kind 4 is the link's TOUCH" in text
    assert f"kinds {msg.free_text()}" in text
    # the same line from the CLI, exit 2, no traceback
    assert main(["run", "--behaviour", str(folder)]) == 2
    out = capsys.readouterr().err.strip()
    assert "kind 4 is the link's TOUCH" in out and "\n" not in out and "Traceback" not in out


def test_the_free_kinds_are_what_the_link_leaves_and_the_guide_says_so():
    assert set(msg.FREE_KINDS) == set(range(1, 16)) - {m[0] for m in msg.MESSAGES}
    guide = (Path(__file__).resolve().parents[1] / "docs" / "writing-a-behaviour.md").read_text()
    assert f"kinds {msg.free_text()}" in guide
    # the guide's claim that another behaviour's kinds are free for yours
    used = {row[0] for b in ("thesis", "aggregate") for row in registry.load(b).messages}
    assert used and used <= set(msg.FREE_KINDS)
    assert "kinds are per behaviour" in guide


def test_two_behaviours_may_give_one_kind_their_own_messages(tmp_path, monkeypatch, capsys):
    """An installed behaviour with kind 7 and 8 messages of its own (aggregate
    has LEAVE at 7, the thesis RELEASE at 8): `touchswarm behaviours` marks
    none BROKEN, and each behaviour's codec, DBC and recordings use its own."""
    folder = scaffold(tmp_path, "other", own_kinds)
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.setattr(registry, "_entry_points", lambda: (("other", "other"),))
    assert main(["behaviours"]) == 0
    listing = capsys.readouterr().out
    assert "BROKEN" not in listing
    assert "QUIT (kind 7, up), NUDGE (kind 8, down)" in listing
    assert "LEAVE (kind 7, up)" in listing and "RELEASE (kind 8, down)" in listing
    assert {"thesis", "aggregate", "other"} <= {ln.split()[0] for ln in listing.splitlines()
                                                if ln and not ln[0].isspace()}

    other = registry.load(folder)
    agg = registry.load("aggregate")
    assert codec.schema(other).names[7] == "QUIT" and codec.schema(agg).names[7] == "LEAVE"
    assert codec.schema(registry.load("thesis")).names[8] == "RELEASE"
    assert codec.schema(other).names[8] == "NUDGE" and 8 not in codec.schema(agg).names

    # a decoder made before the behaviour is put in use follows it (a link is
    # made before its engine)
    registry.load("thesis").activate()
    dec = codec.Decoder("robot")
    nudge = can.Message(arbitration_id=msg.can_id(8, 3), is_extended_id=False, data=b"\x01")
    assert dec.decode(nudge) is None                 # a RELEASE needs 4 bytes
    other.activate()
    assert dec.decode(nudge) == (3, 8, (1,))
    assert msg.spec(8)[1] == "NUDGE"
    agg.activate()
    assert 8 not in msg.SCHEMA and msg.spec(7)[1] == "LEAVE"


def test_each_behaviour_records_and_replays_its_own_kind_7_in_one_process(tmp_path, capsys):
    """The scaffold (QUIT at kind 7) and aggregate (LEAVE at 7) over virtual
    CAN, one after the other in one process; both replay identically."""
    folder = scaffold(tmp_path, "other", own_kinds)
    runs = {"other": str(folder), "aggregate": "aggregate"}
    for name, ref in runs.items():
        f = tmp_path / f"{name}.blf"
        assert main(["run", "--seed", "2", "--behaviour", ref, "--set", "quorum=100",
                     "--set", "maxTicks=600", "--link", "can", "--record", str(f),
                     "--json"]) in (0, 1)
        kinds = [msg.split_id(m.arbitration_id)[0] for m in can.BLFReader(str(f))]
        assert kinds.count(7) > 0, f"{name}: no kind 7 recorded: the test proves nothing"
    capsys.readouterr()
    for name in runs:
        # a folder the sidecar names is trusted on the command line (docs/security.md)
        trust = [] if runs[name] == name else ["--trust-behaviour", runs[name]]
        assert main(["replay", str(tmp_path / f"{name}.blf"), "--json", *trust]) == 0
        out = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
        assert out["divergences"] == 0 and out["touches"] > 0, name


def test_dbc_of_a_behaviour_folder_decodes_its_own_message(tmp_path, capsys):
    folder = scaffold(tmp_path, "other", own_kinds)
    out = tmp_path / "other.dbc"
    assert main(["dbc", "--behaviour", str(folder), "--max-node", "8", "--out", str(out)]) == 0
    assert "its own: QUIT, NUDGE" in capsys.readouterr().out
    db = cantools.database.load_file(str(out))
    b = registry.load(folder).activate()
    buf = bytearray(8)
    n = msg.pack(b.spec.NUDGE, (-1,), buf)
    m = db.get_message_by_frame_id(msg.can_id(b.spec.NUDGE, 0))
    assert m.name == "NUDGE_0" and m.senders == ["HOST"]
    assert db.decode_message(m.frame_id, bytes(buf[:n])) == {"dx": -1}
    n = msg.pack(b.spec.LEAVE, (5, 640, -128), buf)
    quit_ = db.get_message_by_frame_id(msg.can_id(b.spec.LEAVE, 3))
    assert quit_.name == "QUIT_3"
    d = db.decode_message(quit_.frame_id, bytes(buf[:n]))
    assert d["seq"] == 5 and d["x"] == pytest.approx(2.5) and d["y"] == -0.5
    # its states name HEARTBEAT.state, not the thesis's
    hb = db.get_message_by_frame_id(msg.can_id(msg.HEARTBEAT, 3))
    n = msg.pack(msg.HEARTBEAT, (b.spec.STATES.index("stay"), 0, 0, 0, 0), buf)
    assert db.decode_message(hb.frame_id, bytes(buf[:n]))["state"] == "stay"
    # the thesis's DBC has neither
    thesis = dbc.build(max_node=8)
    with pytest.raises(KeyError):
        thesis.get_message_by_frame_id(msg.can_id(7, 3))
    assert thesis.get_message_by_frame_id(msg.can_id(8, 0)).name == "RELEASE_0"
    assert main(["dbc", "--behaviour", "nosuch", "--out", str(tmp_path / "x.dbc")]) == 2
    err = capsys.readouterr().err.strip()
    assert "--behaviour" in err and "\n" not in err


def test_two_folders_of_one_name_each_bring_their_own_messages(tmp_path):
    """Two scaffolds named alike in different folders (two projects, or two
    tests): the second's spec.py is its own, not the first's left in
    sys.modules, and so are its message kinds."""
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    a = scaffold(tmp_path / "a", "twin", own_kinds)
    b = scaffold(tmp_path / "b", "twin",
                 lambda t: t.replace('(LEAVE, "LEAVE", UP,', '(LEAVE, "GONE", UP,'))
    assert codec.schema(registry.load(a)).names[7] == "QUIT"
    assert codec.schema(registry.load(b)).names[7] == "GONE"
    assert registry.load(b).spec.__file__ == str(b / "spec.py")
