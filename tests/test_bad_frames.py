"""Bad frames: counted by kind, logged once per kind, never a crash, never a
change of state, on the host side and in the robots' gateway decoder."""

import copy
import logging

import can
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from bridge.host.process import HostProcess
from bridge.host.transport import CanTransport
from bridge.links import codec, open_bus
from bridge.links.canlink import Gateway, private_channel
from firmware_logic import messages as msg
from firmware_logic.behaviours.thesis.robot import Robot
from tests.fakehal import FakeHal
from tests.test_journal import FakeTransport


def frame(ident, data, **kw):
    return can.Message(arbitration_id=ident, data=bytes(data), is_extended_id=False, **kw)


CASES = [
    (codec.UNKNOWN_ID, frame(msg.can_id(12, 3), b"\x00")),   # a free kind nobody declared
    (codec.UNKNOWN_ID, frame(msg.can_id(15, 3), b"")),
    (codec.UNKNOWN_ID, frame(0, b"")),
    (codec.WRONG_DLC, frame(msg.can_id(msg.TOUCH, 3), b"\x01\x02")),
    (codec.WRONG_DLC, frame(msg.can_id(msg.HELLO, 3), b"\x01\x64\x00\x01\x00")),
    (codec.OUT_OF_RANGE, frame(msg.can_id(msg.HELLO, 3), b"\x09\x64\x00\x01")),     # model 9
    (codec.OUT_OF_RANGE, frame(msg.can_id(msg.TOUCH, 3), b"\x00\x01\x01\x02\x01\x64\x00")),
    (codec.OUT_OF_RANGE, frame(msg.can_id(msg.TOUCH, 3), b"\x01\x01\x01\x09\x01\x64\x00")),
    (codec.OUT_OF_RANGE, frame(msg.can_id(msg.HEARTBEAT, 3), b"\x09\0\0\0\0\0\0\0")),
    (codec.OUT_OF_RANGE, frame(msg.can_id(msg.HELLO, 0), b"\x01\x64\x00\x01")),     # node 0
    (codec.WRONG_DIRECTION, frame(msg.can_id(msg.ACK, 3), b"\x01")),
    (codec.EXTENDED, can.Message(arbitration_id=msg.can_id(msg.HELLO, 3), data=b"\x01\x64\x00\x01",
                                 is_extended_id=True)),
    (codec.REMOTE, can.Message(arbitration_id=msg.can_id(msg.HELLO, 3), is_remote_frame=True,
                               dlc=4, is_extended_id=False)),
    (codec.ERROR, can.Message(is_error_frame=True)),
]


def snapshot(h):
    c = h.coord
    return copy.deepcopy((c.nodes, [t.as_tuple() for t in c.touches], sorted(c.by_node), c.power,
                          c.leader, c.outbox, c.acks, c.duplicates, c.rejected, c.step))


def announced_host():
    h = HostProcess(FakeTransport(), weight=500)
    h.handle([(3, msg.HELLO, (1, 100, 1))])
    h.step()
    return h


@pytest.mark.parametrize("fault,f", CASES, ids=[f"{i}-{c[0]}" for i, c in enumerate(CASES)])
def test_each_bad_frame_is_counted_and_changes_nothing(fault, f):
    dec = codec.Decoder("host")
    h = announced_host()
    before = snapshot(h)
    assert dec.decode(f) is None
    assert dec.bad.counts == {fault: 1}
    assert snapshot(h) == before


def test_unannounced_node_is_counted_by_the_host():
    h = announced_host()
    before = snapshot(h)
    h.handle([(9, msg.TOUCH, (1, 2, 2, 3, 2, 100)), (9, msg.HEARTBEAT, (1, 0, 0, 0, 0))])
    assert h.bad_frames() == {codec.UNANNOUNCED: 2}
    assert snapshot(h) == before


def test_logged_once_per_kind_over_a_real_bus(caplog):
    ch = private_channel("bad")
    with open_bus(f"virtual://{ch}") as tx, CanTransport(open_bus(f"virtual://{ch}")) as tr:
        with caplog.at_level(logging.WARNING, logger="bridge.links.codec"):
            for _ in range(3):
                for _, f in CASES:
                    tx.send(f)
            got = []
            for _ in range(20):
                got += tr.poll(0.05)
        assert got == []
        want = {}
        for fault, _ in CASES:
            want[fault] = want.get(fault, 0) + 3
        assert tr.bad_frames() == want
        lines = [r.getMessage() for r in caplog.records]
        assert len(lines) == len(want)
        for fault in want:
            assert sum(f"({fault})" in line for line in lines) == 1


frames = st.builds(
    lambda ident, data, ext, rtr, err, dlc: can.Message(
        arbitration_id=ident if not ext else ident | (1 << 20), data=data, dlc=dlc,
        is_extended_id=ext, is_remote_frame=rtr, is_error_frame=err),
    st.integers(0, 0x7FF), st.binary(max_size=8), st.booleans(), st.booleans(),
    st.booleans(), st.integers(0, 8))
mostly_ours = st.one_of(
    frames,
    st.builds(lambda k, n, data: frame(msg.can_id(k, n), data),
              st.sampled_from(sorted(msg.SCHEMA)), st.integers(0, 127), st.binary(max_size=8)))


@settings(max_examples=400, deadline=None)
@given(st.lists(mostly_ours, max_size=30))
def test_random_frames_to_the_host(fs):
    h = announced_host()
    dec = codec.Decoder("host")
    for f in fs:
        before = snapshot(h)
        bad_before = dec.bad.total()
        m = dec.decode(f)
        if m is None:
            assert snapshot(h) == before
            continue
        assert dec.bad.total() == bad_before
        node, kind, fields = m
        assert kind in codec.ROBOT_KINDS and 1 <= node <= 127
        h.handle([m])
        h.step()


@settings(max_examples=400, deadline=None)
@given(st.lists(mostly_ours, max_size=30))
def test_random_frames_to_the_robots_decoder(fs):
    gw = Gateway(bus=None, nodes=[1, 2, 3])
    robots = {n: Robot(n, 1, 1, 45, 2, 100) for n in (1, 2, 3)}
    for f in fs:
        inbox_before = {n: list(q) for n, q in gw.inbox.items()}
        bad_before = gw.decoder.bad.total()
        gw.deliver(f)
        if gw.decoder.bad.total() > bad_before or gw.inbox == inbox_before:
            assert {n: list(q) for n, q in gw.inbox.items()} == inbox_before
    for n, r in robots.items():
        hal = FakeHal()
        hal.inbox = [(k, list(fields)) for k, fields in gw.inbox[n]]
        for kind, fields in hal.inbox:
            assert kind in codec.HOST_KINDS
        r.step(hal)           # the FSM takes whatever got through without failing


@settings(max_examples=500, deadline=None)
@given(st.integers(0, 0x7FF), st.binary(max_size=8))
def test_random_frames_to_the_firmware_decoder(ident, data):
    """What a MicroPython robot runs: split_id + unpack raise SchemaError or decode."""
    kind, node = msg.split_id(ident)
    assert 0 <= node <= 127
    out = [0] * 6
    try:
        n = msg.unpack(kind, data, out)
    except msg.SchemaError:
        assert kind not in msg.SCHEMA or len(data) != msg.dlc(kind)
        return
    assert n == len(msg.fields(kind))
    buf = bytearray(8)
    assert bytes(buf[:msg.pack(kind, out[:n], buf)]) == data


def test_garbage_from_an_slcan_adapter_is_counted_not_fatal(tmp_path):
    path = tmp_path / "ada"
    with open_bus(f"slcan-pty://{path}") as adapter, \
            CanTransport(open_bus(f"slcan://{path}?settle_ms=0")) as tr:
        adapter.recv(0.05)                      # the host opened the channel
        adapter.pending += b"t2\r" + b"tXYZ4zz\r" + b"t2815GG\r"    # lines python-can cannot parse
        adapter._flush_out()
        adapter.send(can.Message(arbitration_id=msg.can_id(msg.HELLO, 5), data=b"\x01\x64\x00\x01",
                                 is_extended_id=False))
        got = []
        for _ in range(50):
            got += tr.poll(0.02)
            if got:
                break
        assert got == [(5, msg.HELLO, (1, 100, 1))]
        assert tr.bad_frames().get("malformed adapter line", 0) >= 1
