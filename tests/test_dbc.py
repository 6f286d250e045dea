"""The DBC is generated from the schema and decodes what the firmware packs."""

import cantools
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bridge.cli import main
from bridge.links import dbc
from firmware_logic import messages as msg

DB = cantools.database.load_file("docs/touchswarm.dbc")


def field_values(kind, draw_int):
    out = []
    for _, size, signed in msg.fields(kind):
        bits = size * 8
        lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
        out.append(draw_int(lo, hi))
    return out


LINK_KINDS = sorted(m[0] for m in msg.MESSAGES)   # what the shipped (thesis) DBC holds


@pytest.mark.parametrize("kind", LINK_KINDS)
@pytest.mark.parametrize("pick", ["lo", "hi", "mid"])
def test_every_kind_decodes_field_by_field(kind, pick):
    for node in (0, 1, 77, 127):
        if node == 0 and kind not in (msg.HALT, msg.TRANSPORT, msg.ACK):
            continue
        vals = field_values(kind, lambda lo, hi: {"lo": lo, "hi": hi, "mid": (lo + hi) // 3}[pick])
        buf = bytearray(8)
        n = msg.pack(kind, vals, buf)
        m = DB.get_message_by_frame_id(msg.can_id(kind, node))
        assert m.length == n == msg.dlc(kind)
        assert m.name == "%s_%d" % (msg.SCHEMA[kind][0], node)
        decoded = DB.decode_message(msg.can_id(kind, node), bytes(buf[:n]),
                                     decode_choices=False, scaling=False)
        names = [f[0] for f in msg.fields(kind)]
        assert list(decoded) == names
        for name, v in zip(names, vals):
            assert decoded[name] == v, (kind, node, name)


@settings(max_examples=200, deadline=None)
@given(st.data())
def test_random_values_roundtrip(data):
    kind = data.draw(st.sampled_from(LINK_KINDS))
    node = data.draw(st.integers(1, 127))
    vals = field_values(kind, lambda lo, hi: data.draw(st.integers(lo, hi)))
    buf = bytearray(8)
    n = msg.pack(kind, vals, buf)
    decoded = DB.decode_message(msg.can_id(kind, node), bytes(buf[:n]),
                                     decode_choices=False, scaling=False)
    assert [decoded[f[0]] for f in msg.fields(kind)] == vals
    # and cantools encodes to the same bytes the firmware packs
    assert DB.encode_message(msg.can_id(kind, node), decoded, scaling=False,
                             strict=False) == bytes(buf[:n])


def test_shipped_dbc_is_current():
    assert open("docs/touchswarm.dbc", newline="").read() == dbc.dbc_text()


def test_dbc_command(tmp_path, capsys):
    out = tmp_path / "t.dbc"
    assert main(["dbc", "-o", str(out), "--max-node", "4"]) == 0
    db = cantools.database.load_file(str(out))
    assert db.get_message_by_name("TOUCH_4").frame_id == msg.can_id(msg.TOUCH, 4)
    with pytest.raises(SystemExit) as refused:   # argparse refuses the node id
        main(["dbc", "-o", str(out), "--max-node", "200"])
    assert refused.value.code == 2
    assert "expected a node id 1..127" in capsys.readouterr().err


def test_physical_values_units_and_names() -> None:
    """cantools shows patches, power units, state and model names, derived from
    messages.MESSAGES and the thesis spec."""
    hb = DB.get_message_by_frame_id(msg.can_id(msg.HEARTBEAT, 5))
    buf = bytearray(8)
    n = msg.pack(msg.HEARTBEAT, (3, 598, -256, 90, 2), buf)
    d = DB.decode_message(hb.frame_id, bytes(buf[:n]))
    assert d["state"] == "hold"
    assert d["x"] == pytest.approx(598 / 256) and d["y"] == -1.0
    assert hb.get_signal_by_name("x").unit == "patch"
    hello = DB.get_message_by_frame_id(msg.can_id(msg.HELLO, 5))
    n = msg.pack(msg.HELLO, (2, 150, 1), buf)
    d = DB.decode_message(hello.frame_id, bytes(buf[:n]))
    assert d["model"] == "ant" and d["power"] == 1.5
    assert "journalled" in DB.get_message_by_frame_id(msg.can_id(msg.ACK, 0)).comment


def test_a_behaviours_own_message_is_in_its_dbc_with_units():
    """aggregate declares LEAVE (kind 7) in its spec.py: its DBC decodes it
    with physical values; the thesis's DBC does not carry it."""
    from sim_backend import registry
    agg = registry.load("aggregate").activate()     # its kinds in use: pack knows LEAVE
    leave = agg.spec.LEAVE
    db = dbc.build(max_node=8, behaviour=agg)
    m = db.get_message_by_frame_id(msg.can_id(leave, 3))
    assert m.name == "LEAVE_3"
    buf = bytearray(8)
    n = msg.pack(leave, (9, 640, -128), buf)
    d = db.decode_message(m.frame_id, bytes(buf[:n]))
    assert d["seq"] == 9 and d["x"] == pytest.approx(2.5) and d["y"] == -0.5
    thesis = dbc.build(max_node=8)
    with pytest.raises(KeyError):
        thesis.get_message_by_frame_id(msg.can_id(leave, 3))


def test_declared_messages_are_checked():
    bad = [((1, "X", msg.UP, "", (("a", 1, 0, 1, "", None, None, ""),)), "kind 1 is the link's HALT"),
           ((9, "TOUCH", msg.UP, "", ()), "the name is the link's"),
           ((0, "X", msg.UP, "", ()), "not a 4-bit kind the link leaves free"),
           ((9, "X", msg.UP, "", (("a", 4, 0, 1, "", None, None, ""),)), "1 or 2"),
           ((9, "X", msg.CAPTURE, "", ()), "direction"),
           ((9, "X", msg.UP, "", tuple(("a%d" % i, 2, 0, 1, "", None, None, "")
                                       for i in range(5))), "8 bytes")]
    for row, words in bad:
        with pytest.raises(msg.SchemaError, match=words):
            msg.activate([row])
    assert 9 not in msg.SCHEMA
    twice = ((9, "A", msg.UP, "", ()), (9, "B", msg.DOWN, "", ()))
    with pytest.raises(msg.SchemaError, match="kind 9 is declared twice: A and B"):
        msg.check(twice)
