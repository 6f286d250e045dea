"""`touchswarm dbc --keyed`: the DBC of a keyed bus decodes the frames the
project's own sealing code (bridge/links/secoc.py) puts on it."""

from __future__ import annotations

import cantools
import pytest

from bridge.cli import main
from bridge.links import dbc, secoc
from bridge.links.codec import BadFrames, encode
from firmware_logic import messages as msg
from firmware_logic.behaviours.thesis.spec import RELEASE

KEYS = {n: bytes([n]) * 16 for n in range(1, 9)}


@pytest.fixture(scope="module")
def keyed(tmp_path_factory):
    """The keyed DBC as the command writes it, read back from its text."""
    out = tmp_path_factory.mktemp("dbc") / "keyed.dbc"
    assert main(["dbc", "--keyed", "--max-node", "8", "-o", str(out)]) == 0
    return cantools.database.load_file(str(out))


def raw(db, frame):
    return db.decode_message(frame.arbitration_id, bytes(frame.data), decode_choices=False,
                             scaling=False)


def host_and_robots():
    """A sealer (host) and an opener (robots) with one host command taken by
    every robot, so the robots may seal reports."""
    sealer, robots = secoc.Sealer(KEYS), secoc.Opener(KEYS, BadFrames("robots"))
    for frame in sealer.seal(encode(0, msg.ACK, (0,))):     # one per keyed robot
        assert robots.open(frame) is not None
    return sealer, robots


@pytest.mark.parametrize("kind, fields", [(msg.HALT, (1,)), (msg.ACK, (7,)),
                                          (msg.TRANSPORT, (3, 1, -1)),
                                          (RELEASE, (-4, 2, -3, 5))])   # the thesis's own
def test_a_sealed_host_command_decodes_to_its_fields_freshness_and_mac(keyed, kind, fields):
    from sim_backend import registry
    registry.load("thesis").activate()      # its RELEASE in use: the sealer seals it
    sealer, _ = host_and_robots()
    (frame,) = sealer.seal(encode(2, kind, fields))
    m = keyed.get_message_by_frame_id(frame.arbitration_id)
    assert m.length == len(frame.data) == 8 != msg.dlc(kind)
    d = raw(keyed, frame)
    names = [f[0] for f in msg.spec(kind)[4]]
    assert list(d) == names + ["fv", "mac"]
    assert tuple(d[n] for n in names) == fields
    k = secoc.fv_bytes(msg.dlc(kind))
    assert m.get_signal_by_name("fv").length == 8 * k
    assert d["fv"] == sealer.fv[2] & ((1 << (8 * k)) - 1)
    assert d["mac"] == int.from_bytes(frame.data[-secoc.MAC_BYTES:], "big")


def test_a_broadcast_is_one_sealed_frame_per_robot_and_has_no_node_0_message(keyed):
    sealer, _ = host_and_robots()
    frames = sealer.seal(encode(0, msg.HALT, (2,)))
    assert len(frames) == len(KEYS)
    for frame in frames:
        assert raw(keyed, frame)["reason"] == 2
    with pytest.raises(KeyError):
        keyed.get_message_by_frame_id(msg.can_id(msg.HALT, 0))


@pytest.mark.parametrize("kind, fields, sealed", [
    # TOUCH: seq, sx, sy and near, the index of (rx - sx, ry - sy) in NEAR
    (msg.TOUCH, (7, -3, 4, -2, 5, 250), {"seq": 7, "sx": -2, "sy": 5,
                                         "near": msg.NEAR.index((-1, -1))}),
    (msg.TOUCH, (255, 10, -10, 9, -11, 250), {"seq": 255, "sx": 9, "sy": -11,
                                              "near": msg.NEAR.index((1, 1))}),
    # HEARTBEAT: x and y in whole patches, no heading
    (msg.HEARTBEAT, (4, 5 * 256, -7 * 256, 90, 200), {"state": 4, "x": 5, "y": -7,
                                                      "step": 200}),
])
def test_a_sealed_report_decodes_to_its_sealed_fields(keyed, kind, fields, sealed):
    sealer, robots = host_and_robots()
    sealer.hellos[4] = (1, 250, 1)
    for _ in range(3):                 # r counts the reports since the last command
        frame = robots.seal_report(4, kind, fields)
    assert sealer.open_report(frame, 4) is not None        # a genuine one
    m = keyed.get_message_by_frame_id(frame.arbitration_id)
    assert m.length == len(frame.data) == 8
    d = raw(keyed, frame)
    assert list(d) == list(sealed) + ["fv", "mac"]
    assert {n: d[n] for n in sealed} == sealed
    assert d["fv"] == robots.r[4] & 0xFF == 3
    assert d["mac"] == int.from_bytes(frame.data[-secoc.MAC_BYTES:], "big")


def test_sealed_fields_keep_their_units_and_value_tables(keyed):
    _, robots = host_and_robots()
    hb = robots.seal_report(5, msg.HEARTBEAT, (3, 2 * 256, -256, 0, 1))
    d = keyed.decode_message(hb.arbitration_id, bytes(hb.data))
    assert d["state"] == "hold" and d["x"] == 2 and d["y"] == -1
    m = keyed.get_message_by_frame_id(hb.arbitration_id)
    assert m.get_signal_by_name("x").unit == "patch"
    assert "r" in m.get_signal_by_name("fv").comment
    touch = robots.seal_report(5, msg.TOUCH, (1, 0, 0, 1, 0, 250))
    assert keyed.decode_message(touch.arbitration_id, bytes(touch.data))["near"] == \
        "rx-sx=-1 ry-sy=0"


def test_a_keyed_hello_decodes_with_its_floor_block(keyed):
    hello = encode(3, msg.HELLO, (2, 150, 1))
    frame = secoc.seal_hello(KEYS[3], hello, last=0x12345)
    d = raw(keyed, frame)
    assert (d["model"], d["power"], d["version"]) == (2, 150, 1)
    assert d["fv"] == (0x12345 >> secoc.BLOCK) & 0xFF
    assert keyed.get_message_by_frame_id(frame.arbitration_id).length == len(frame.data) == 8


def test_every_sealed_message_has_the_sealed_length_not_the_plain_one(keyed):
    """The plain DBC's lengths (1, 3, 7, 8 bytes) would decode a sealed frame
    as a wrong length and read its freshness and MAC as payload."""
    plain = dbc.build(max_node=8)
    for m in keyed.messages:
        kind = msg.split_id(m.frame_id)[0]
        if msg.spec(kind)[2] == msg.CAPTURE:
            assert m.length == plain.get_message_by_frame_id(m.frame_id).length
            continue
        assert m.length == 8 and [s.name for s in m.signals][-2:] == ["fv", "mac"]
    # the plain layout reads a sealed TOUCH wrongly: rx is the sealed sx, ...
    _, robots = host_and_robots()
    frame = robots.seal_report(2, msg.TOUCH, (7, -3, 4, -2, 5, 250))
    assert raw(plain, frame)["rx"] == -2 != -3
    assert raw(keyed, frame)["sx"] == -2


def test_the_plain_dbc_still_decodes_plain_frames(keyed):
    plain = dbc.build(max_node=8)
    for kind, fields in [(msg.TOUCH, (7, -3, 4, -2, 5, 250)), (msg.TRANSPORT, (3, 1, -1)),
                         (msg.HEARTBEAT, (4, 300, -7, 90, 200))]:
        frame = encode(6, kind, fields)
        assert plain.get_message_by_frame_id(frame.arbitration_id).length == msg.dlc(kind)
        d = raw(plain, frame)
        assert tuple(d.values()) == fields
    assert plain.get_message_by_frame_id(msg.can_id(msg.HALT, 0)).length == 1


def test_a_behaviours_own_report_is_in_its_keyed_dbc_in_whole_patches():
    """aggregate's LEAVE (seq, x, y in Q8: 5 bytes) travels sealed with x and
    y in whole patches."""
    from firmware_logic.behaviours.aggregate.spec import LEAVE
    from sim_backend import registry
    agg = registry.load("aggregate").activate()
    try:
        db = dbc.build(max_node=8, behaviour=agg, keyed=True)
        _, robots = host_and_robots()
        frame = robots.seal_report(5, LEAVE, (3, 3 * 256 + 100, -2 * 256 - 20))
    finally:
        registry.load("thesis").activate()
    d = raw(db, frame)
    assert (d["seq"], d["x"], d["y"]) == (3, 3, -2)
    assert db.get_message_by_frame_id(frame.arbitration_id).length == 8


def test_a_field_named_like_the_freshness_signal_is_refused():
    from types import SimpleNamespace

    from sim_backend import registry
    row = (9, "X", msg.UP, "", (("fv", 1, 0, 1, "", None, None, ""),))
    own = SimpleNamespace(spec=registry.load().spec, messages=(row,), name="own",
                          module_name="test_dbc_keyed.own")
    assert dbc.build(max_node=2, behaviour=own).get_message_by_name("X_2").length == 1
    with pytest.raises(ValueError, match="message X: a field named 'fv' clashes"):
        dbc.build(max_node=2, behaviour=own, keyed=True)


def test_a_report_that_does_not_fit_the_sealed_form_is_refused_with_its_name():
    from types import SimpleNamespace

    from sim_backend import registry
    row = (9, "BIG", msg.UP, "", tuple((f"a{i}", 1, 0, 1, "", None, None, "")
                                       for i in range(5)))
    own = SimpleNamespace(spec=registry.load().spec, messages=(row,), name="big",
                          module_name="test_dbc_keyed.big")
    with pytest.raises(secoc.SecocError, match="message BIG: its sealed form takes 5 bytes"):
        dbc.build(max_node=2, behaviour=own, keyed=True)
