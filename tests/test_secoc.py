"""Authenticated host commands (bridge/links/secoc.py): a robot passes on a
host command only when its MAC verifies under that robot's key and its
freshness value is above the last one accepted; everything else is counted
by kind and dropped."""

from __future__ import annotations

import json

import can
import pytest

from bridge.errors import BridgeError
from bridge.links import secoc
from bridge.host.transport import CanTransport
from bridge.links import open_bus
from bridge.links.canlink import private_channel
from bridge.links.codec import BadFrames, Decoder, encode
from firmware_logic import messages as msg

KEYS = {n: bytes([n]) * 16 for n in range(1, 6)}
OTHER = {n: bytes([n + 100]) * 16 for n in range(1, 6)}


def robot_side(keys=KEYS):
    bad = BadFrames("robot")
    return secoc.Opener(keys, bad), Decoder("robot", bad), bad


def passed(opener, decoder, frame):
    f = opener.open(frame)
    return None if f is None else decoder.decode(f)


@pytest.mark.parametrize("kind, fields", [(msg.HALT, (1,)), (msg.ACK, (7,)),
                                          (msg.TRANSPORT, (3, 1, -1))])
def test_a_sealed_command_fills_8_bytes_and_opens_to_the_same_message(kind, fields):
    sealer = secoc.Sealer(KEYS)
    opener, decoder, bad = robot_side()
    (frame,) = sealer.seal(encode(2, kind, fields))
    assert frame.dlc == 8 and bytes(frame.data[:msg.dlc(kind)]) == bytes(
        encode(2, kind, fields).data)
    assert passed(opener, decoder, frame) == (2, kind, fields)
    assert bad.counts == {}


def test_plain_forged_tampered_replayed_and_wrong_key_commands_are_dropped_and_counted():
    sealer = secoc.Sealer(KEYS)
    opener, decoder, bad = robot_side()
    ack = sealer.seal(encode(3, msg.ACK, (5,)))[0]
    assert passed(opener, decoder, ack) == (3, msg.ACK, (5,))
    # the same genuine frame again: its MAC verifies, its counter is used up
    assert passed(opener, decoder, ack) is None and bad.counts == {secoc.STALE: 1}
    # a plain command, as every host sent before keys
    assert passed(opener, decoder, encode(3, msg.HALT, (0,))) is None
    assert bad.counts[secoc.UNAUTHENTICATED] == 1
    # a broadcast: never sealed by a keyed host (it sends one per robot)
    assert passed(opener, decoder, can.Message(arbitration_id=msg.can_id(msg.HALT, 0),
                                               is_extended_id=False, data=bytes(8))) is None
    assert bad.counts[secoc.UNAUTHENTICATED] == 2
    # a genuine frame with its payload changed (ACK seq 5 -> 6)
    t = sealer.seal(encode(3, msg.ACK, (5,)))[0]
    forged = can.Message(arbitration_id=t.arbitration_id, is_extended_id=False,
                         data=bytes([6]) + bytes(t.data[1:]))
    assert passed(opener, decoder, forged) is None and bad.counts[secoc.BAD_MAC] == 1
    # sealed with another robot's, or another swarm's, key
    assert passed(opener, decoder, secoc.Sealer(OTHER).seal(encode(3, msg.HALT, (0,)))[0]) \
        is None
    assert bad.counts[secoc.BAD_MAC] == 2
    moved = can.Message(arbitration_id=msg.can_id(msg.ACK, 4), is_extended_id=False,
                        data=bytes(t.data))        # node 3's frame sent to node 4
    assert passed(opener, decoder, moved) is None and bad.counts[secoc.BAD_MAC] == 3
    # a replayed TRANSPORT (16-bit counter on the wire) is read as the next
    # window's value, so its MAC fails: dropped as well
    step = sealer.seal(encode(3, msg.TRANSPORT, (1, 1, 0)))[0]
    assert passed(opener, decoder, step) == (3, msg.TRANSPORT, (1, 1, 0))
    assert passed(opener, decoder, step) is None and bad.counts[secoc.BAD_MAC] == 4
    # the host's next genuine command still passes after all of that
    assert passed(opener, decoder, sealer.seal(encode(3, msg.ACK, (6,)))[0]) == \
        (3, msg.ACK, (6,))


def test_a_broadcast_becomes_one_sealed_frame_per_keyed_robot():
    frames = secoc.Sealer(KEYS).seal(encode(0, msg.HALT, (2,)))
    assert [msg.split_id(f.arbitration_id) for f in frames] == [(msg.HALT, n) for n in KEYS]
    opener, decoder, bad = robot_side()
    assert [passed(opener, decoder, f) for f in frames] == [(n, msg.HALT, (2,)) for n in KEYS]


def test_robot_reports_pass_unchanged():
    opener, decoder, bad = robot_side()
    hello = encode(2, msg.HELLO, (1, 100, 1))
    assert opener.open(hello) is hello


def test_truncated_counters_follow_the_host_across_many_frames():
    """TRANSPORT carries 16 bits of the counter; 70,000 commands (more than one
    wrap of those bits) with a lost stretch in between all verify."""
    sealer = secoc.Sealer({1: KEYS[1]})
    opener, decoder, bad = robot_side({1: KEYS[1]})
    ok = 0
    for i in range(70_000):
        f = sealer.seal(encode(1, msg.TRANSPORT, (1 + i % 200, 0, 1)))[0]
        if 30_000 <= i < 30_000 + 60_000 // 2 and i % 1000:   # frames lost on the bus
            continue
        ok += passed(opener, decoder, f) is not None
    assert bad.counts == {} and opener.last[1] == sealer.fv[1] == 70_000
    assert ok == 70_000 - 30_000 + 30


def test_a_restarted_host_continues_above_every_counter_it_used(tmp_path):
    store = tmp_path / "keys.toml.fv.json"
    opener, decoder, bad = robot_side()
    first = secoc.Sealer(KEYS, secoc.FreshnessStore(store))
    for seq in range(1, 300):
        assert passed(opener, decoder, first.seal(encode(1, msg.ACK, (seq % 250,)))[0])
    assert json.loads(store.read_text())["1"] >= first.fv[1]
    again = secoc.Sealer(KEYS, secoc.FreshnessStore(store))     # the host restarted
    assert passed(opener, decoder, again.seal(encode(1, msg.ACK, (9,)))[0]) == (1, msg.ACK, (9,))
    # a host that forgot its counters would be refused as a replay
    amnesiac = secoc.Sealer(KEYS)
    assert passed(opener, decoder, amnesiac.seal(encode(1, msg.ACK, (9,)))[0]) is None
    assert bad.counts == {secoc.STALE: 1}


K1 = "11" * 16


def private(p, data):
    """A file only its owner may read, as `touchswarm keys new` writes them."""
    p.write_bytes(data if isinstance(data, bytes) else data.encode())
    p.chmod(0o600)
    return p


@pytest.mark.parametrize("text, needle", [
    ("", "no [keys] table"),
    ("[keys]\n", "no [keys] table"),
    ("[keys]\n1 = \"00\"\n", "node 1: expected 32 hex digits"),
    ("[keys]\n1 = \"zz" + "0" * 30 + "\"\n", "node 1: expected 32 hex digits"),
    ("[keys]\n0 = \"" + K1 + "\"\n", "key '0': expected a node id 1..127"),
    ("[keys]\nx = \"" + K1 + "\"\n", "key 'x': expected a node id"),
    ("[keys]\n1 = 5\n", "node 1: expected 32 hex digits"),
    ("[keys\n", "not valid TOML"),
    # each of these was a traceback or silently accepted
    ("[keys]\n\"\u00b2\" = \"" + K1 + "\"\n", "key '\u00b2': expected a node id"),
    ("[keys]\n1 = \"\u00b2" + "1" * 31 + "\"\n", "node 1: expected 32 hex digits"),
    ("[keys]\n1 = \"" + "0" * 32 + "\"\n", "node 1: an all-zero key is no secret"),
    ("[keys]\n1 = \"" + K1 + "\"\n01 = \"" + "22" * 16 + "\"\n",
     "node 1 is given twice ('1' and '01')"),
    ("[keys]\n1 = \"" + K1 + "\"\n2 = \"" + K1 + "\"\n", "nodes 1 and 2 have the same key"),
])
def test_bad_key_files_are_refused_in_one_line(tmp_path, text, needle):
    p = private(tmp_path / "k.toml", text)
    with pytest.raises(secoc.SecocError) as err:
        secoc.load_keys(p)
    assert needle in str(err.value) and "\n" not in str(err.value)
    assert isinstance(err.value, BridgeError)


def test_key_files_others_may_read_devices_fifos_and_huge_files_are_refused(tmp_path):
    import os
    good = "[keys]\n1 = \"" + K1 + "\"\n"
    shared = private(tmp_path / "shared.toml", good)
    shared.chmod(0o644)
    fifo = tmp_path / "fifo.toml"
    os.mkfifo(fifo)          # reading it would wait for a writer for ever
    huge = private(tmp_path / "huge.toml", "#" * (secoc.MAX_FILE + 1))
    for path, needle in [(shared, "mode 0644 lets others read it; keys must be private: "
                                  f"chmod 600 {shared}"),
                         (fifo, "not a regular file"), ("/dev/zero", "not a regular file"),
                         (huge, f"{secoc.MAX_FILE + 1} bytes; such a file is at most")]:
        with pytest.raises(secoc.SecocError) as err:
            secoc.load_keys(path)
        assert needle in str(err.value) and "\n" not in str(err.value), err.value
    shared.chmod(0o600)
    assert secoc.load_keys(shared) == {1: bytes.fromhex(K1)}


@pytest.mark.parametrize("text, needle", [
    ('{"1": null}', "node 1: counter null; expected an integer 0..4294967295"),
    ('{"1": -5}', "node 1: counter -5; expected an integer"),
    ('{"1": 2.5}', "node 1: counter 2.5; expected an integer"),
    ('{"1": true}', "node 1: counter true; expected an integer"),
    ('{"1": 4294967296}', "node 1: counter 4294967296; expected an integer"),
    ('{"1": 5, "01": 6}', "node 1 is given twice"),
    ('{"\u00b2": 5}', "expected a node id"),
    ('[1, 2]', "expected an object of node: counter"),
    ('{"1": ', "not JSON"),
])
def test_bad_freshness_files_are_refused_in_one_line_before_any_command(tmp_path, text, needle):
    p = tmp_path / "k.toml.fv.json"
    p.write_text(text)
    with pytest.raises(secoc.SecocError) as err:
        secoc.Sealer(KEYS, secoc.FreshnessStore(p))
    msg_ = str(err.value)
    assert needle in msg_ and "\n" not in msg_ and "rekey" in msg_, msg_


def test_a_spent_counter_is_refused_at_start_and_reaching_the_end_is_a_typed_stop(tmp_path):
    p = tmp_path / "k.toml.fv.json"
    p.write_text(json.dumps({"1": secoc.FV_MAX}))
    with pytest.raises(secoc.SecocError, match="node 1: freshness counter at its "
                                                       "end .*rekey: `touchswarm keys new"):
        secoc.Sealer(KEYS, secoc.FreshnessStore(p))
    p.write_text(json.dumps({"1": secoc.FV_MAX - 2}))
    sealer = secoc.Sealer(KEYS, secoc.FreshnessStore(p))
    opener, decoder, bad = robot_side()
    for seq in (1, 2):
        assert passed(opener, decoder, sealer.seal(encode(1, msg.ACK, (seq,)))[0])
    with pytest.raises(secoc.SecocError) as err:
        sealer.seal(encode(1, msg.ACK, (3,)))
    assert "\n" not in str(err.value) and isinstance(err.value, BridgeError)


def test_keys_new_writes_owner_only_keys_that_load(tmp_path):
    from bridge.cli import main
    out = tmp_path / "k.toml"
    assert main(["keys", "new", "--nodes", "7", "--out", str(out)]) == 0
    assert oct(out.stat().st_mode & 0o777) == "0o600"
    keys = secoc.load_keys(out)
    assert sorted(keys) == list(range(1, 8)) and len(set(keys.values())) == 7
    assert main(["keys", "new", "--out", str(out)]) == 2        # never overwritten
    assert secoc.load_keys(out) == keys


# -- HELLO: key confirmation and the robots' freshness floor ----

def hello(node, opener):
    return opener.hello(encode(node, msg.HELLO, (1, 100, 1)))


def test_commands_captured_before_a_robot_restart_or_in_a_past_mission_are_refused(tmp_path):
    """The robots keep their counters (simulated: KEYS.robots.fv.json; a real
    robot: flash), reserved ahead like the host's, and their HELLO names the
    floor, so the host continues above it and nothing sealed replays."""
    store = tmp_path / "keys.toml.robots.fv.json"
    sealer = secoc.Sealer(KEYS)                    # one host throughout
    opener, decoder, bad = robot_side()
    opener = secoc.Opener(KEYS, bad, secoc.FreshnessStore(store))
    assert sealer.open_hello(hello(2, opener), 2) is not None
    captured = [sealer.seal(encode(2, k, f))[0] for k, f in
                [(msg.ACK, (0,)), (msg.TRANSPORT, (1, 1, 0)), (msg.HALT, (0,))]]
    assert all(passed(opener, decoder, f) for f in captured)
    for _ in range(2):                             # robots restarted, then a next mission
        opener = secoc.Opener(KEYS, bad, secoc.FreshnessStore(store))
        assert [passed(opener, decoder, f) for f in captured] == [None] * 3
        # the restarted robot's HELLO moves the host above its floor at once
        assert sealer.open_hello(hello(2, opener), 2) is not None
        assert passed(opener, decoder, sealer.seal(encode(2, msg.ACK, (1,)))[0]) == \
            (2, msg.ACK, (1,))
    assert bad.counts.get(secoc.BAD_MAC, 0) + bad.counts.get(secoc.STALE, 0) == 6


def test_a_host_that_lost_its_freshness_file_recovers_from_the_hello_with_a_message(
        tmp_path, caplog):
    opener, decoder, bad = robot_side()
    old = secoc.Sealer(KEYS, secoc.FreshnessStore(tmp_path / "k.fv.json"))
    for seq in range(1, 2000):
        assert passed(opener, decoder, old.seal(encode(4, msg.ACK, (seq % 250,)))[0])
    lost = secoc.Sealer(KEYS, secoc.FreshnessStore(tmp_path / "gone.fv.json"))
    assert passed(opener, decoder, lost.seal(encode(4, msg.ACK, (1,)))[0]) is None  # stale
    with caplog.at_level("WARNING"):
        assert lost.open_hello(hello(4, opener), 4) is not None
    assert "robot 4 has taken commands of this key file up to counter" in caplog.text
    assert "gone.fv.json lost or older?): continuing above it" in caplog.text
    assert passed(opener, decoder, lost.seal(encode(4, msg.ACK, (2,)))[0]) == (4, msg.ACK, (2,))


def test_the_one_block_hello_macs_are_the_cmac():
    for b in (0, 1, 255, 4095, 0xFFFFFF):
        assert secoc._hello_macs(KEYS[1], 0x281, b"\x01\x64\x00\x01", range(b, b + 1)) == \
            secoc._mac(KEYS[1], 0x281, b"\x01\x64\x00\x01", b)


def test_mac_failures_are_counted_per_robot_and_lock_it_out_past_the_threshold(caplog):
    sealer = secoc.Sealer(KEYS)
    bad = BadFrames("robot")
    opener, decoder = secoc.Opener(KEYS, bad, lockout=8), Decoder("robot", bad)
    forged = secoc.Sealer(OTHER)
    with caplog.at_level("WARNING"):
        for i in range(8):
            assert passed(opener, decoder, forged.seal(encode(3, msg.HALT, (0,)))[0]) is None
    assert opener.failed[3] == 8 and opener.failed[2] == 0 and opener.locked == {3}
    assert "robot 3: 8 host commands failed their MAC" in caplog.text and "locked out" in \
        caplog.text
    # locked out: not even the host is obeyed (a brute force cannot go on)
    assert passed(opener, decoder, sealer.seal(encode(3, msg.HALT, (0,)))[0]) is None
    assert bad.counts[secoc.LOCKED] == 1
    assert passed(opener, decoder, sealer.seal(encode(2, msg.HALT, (0,)))[0]) == (2, msg.HALT, (0,))


def test_the_host_drops_forged_hellos_and_locks_out_a_node_forged_past_the_threshold(caplog):
    bus_url = f"virtual://{private_channel('lock')}"
    with open_bus(bus_url) as robots_bus, open_bus(bus_url) as host_bus:
        host = CanTransport(host_bus, sealer=secoc.Sealer(KEYS))
        opener = secoc.Opener(KEYS, BadFrames("robot"))
        robots_bus.send(hello(1, opener))
        assert [m[:2] for m in host.poll(1.0)] == [(1, msg.HELLO)]       # confirmed
        alien = secoc.Opener(OTHER, BadFrames("alien"))
        with caplog.at_level("WARNING"):
            for _ in range(secoc.HELLO_LOCKOUT):
                robots_bus.send(hello(1, alien))
                robots_bus.send(encode(1, msg.HELLO, (1, 100, 1)))       # plain
            robots_bus.send(encode(1, msg.HEARTBEAT, (1, 0, 0, 0, 0)))
            robots_bus.send(hello(2, opener))
            got = []
            while len(got) < 1:
                got += host.poll(1.0)
        assert [m[:2] for m in got] == [(2, msg.HELLO)]
        bad = host.bad_frames()
        assert bad[secoc.HELLO_BAD_MAC] + bad[secoc.HELLO_PLAIN] == secoc.HELLO_LOCKOUT
        assert bad[secoc.LOCKED_NODE] == secoc.HELLO_LOCKOUT + 1
        assert "robot 1: 16 HELLOs failed authentication" in caplog.text


@pytest.mark.parametrize("host_keys, robot_keys, needle", [
    (KEYS20 := {n: bytes([n, 9]) * 8 for n in range(1, 21)}, None,
     "sends HELLO without a MAC: it has no key file; give `touchswarm robots` the same "
     "--keys FILE"),
    (None, KEYS20, "sends authenticated HELLOs: it has a key file; give `touchswarm host` "
                   "the same --keys FILE"),
    (KEYS20, {n: bytes([n, 10]) * 8 for n in range(1, 21)},
     "'s MAC fails with this key file: host and robots have different key files"),
])
def test_a_key_mismatch_ends_the_host_in_one_line_within_a_few_ticks(host_keys, robot_keys,
                                                                     needle):
    """Host keyed and robots not, robots keyed and host not, or two key files:
    the robots would drop every host command (the host once said
    DELIVERED, exit 0). The host stops with a LinkError, a BridgeError: the
    CLI prints its one line and exits 1."""
    from bridge.host.process import HostProcess
    from bridge.host.swarm import swarm_engine
    from bridge.links.errors import LinkError
    from hil_tests.test_can_mission import TICK, Lockstep, SimClock
    from sim_backend import scenario

    sc = scenario.load("default")
    url = f"virtual://{private_channel('mismatch')}"
    clock = SimClock()
    with open_bus(url) as rb:
        engine = swarm_engine(sc, 1, rb, keys=robot_keys)
        sealer = secoc.Sealer(host_keys) if host_keys is not None else None
        host = HostProcess(Lockstep(CanTransport(open_bus(url), sealer=sealer), engine, clock),
                           sc.weight_centi, sc.homeX, sc.homeY, tick_seconds=TICK)
        with host.transport, pytest.raises(LinkError) as err:
            host.run(max_ticks=400, clock=clock)
    text = str(err.value)
    assert text.startswith("robot ") and needle in text and "\n" not in text
    assert isinstance(err.value, BridgeError)
    assert host.tick <= 12 and not host.coord.done()


def test_robots_that_get_stale_commands_say_hello_again_so_a_host_without_counters_recovers(
        tmp_path, caplog):
    """The host restarted without its freshness file while the robots ran on:
    its commands are stale to them; a robot then repeats its HELLO (every
    RESYNC ticks at most), which names its floor, and the host continues
    above it with a one-line warning instead of being refused for ever."""
    from bridge.links.canlink import Gateway
    url = f"virtual://{private_channel('resync')}"
    with open_bus(url) as rb, open_bus(url) as hb:
        gw = Gateway(rb, [1, 2], keys=KEYS, fresh=secoc.FreshnessStore(tmp_path / "r.json"))
        first = CanTransport(hb, sealer=secoc.Sealer(KEYS))
        gw.robot_send(1, msg.HELLO, (1, 100, 1, 0, 0, 0))
        gw.flush()
        assert [m[:2] for m in first.poll(1.0)] == [(1, msg.HELLO)]
        for seq in range(1, 300):
            first.send(1, msg.ACK, (seq % 200,))
        gw.drain(299)
        assert gw.received == 299
        again = CanTransport(hb, sealer=secoc.Sealer(KEYS, secoc.FreshnessStore(
            tmp_path / "lost.fv.json")))                 # restarted, counters lost
        again.send(1, msg.ACK, (1,))
        gw.drain(1)
        assert gw.received == 299 and gw.decoder.bad.counts == {secoc.STALE: 1}
        assert gw.flush() == 1                            # the robot's HELLO again
        with caplog.at_level("WARNING"):
            assert [m[:2] for m in again.poll(1.0)] == [(1, msg.HELLO)]
        assert "robot 1 has taken commands of this key file up to counter" in caplog.text
        again.send(1, msg.ACK, (2,))
        gw.drain(1)
        assert gw.received == 300 and gw.robot_recv(1) is not None
        # replayed commands make no HELLO storm: one per RESYNC ticks
        replay = again.sealer.seal(encode(1, msg.ACK, (3,)))[0]
        sent = []
        for _ in range(secoc.RESYNC + 1):
            hb.send(replay)
            gw.drain(1)
            sent.append(gw.flush())
        assert sum(sent) == 1 and sent[:secoc.RESYNC - 2] == [0] * (secoc.RESYNC - 2)


def test_with_keys_a_hello_of_a_node_the_key_file_lacks_is_dropped():
    sealer = secoc.Sealer({1: KEYS[1]})
    sealer.bad = BadFrames("host")
    forged = secoc.Opener({9: KEYS[2]}, BadFrames("f")).hello(encode(9, msg.HELLO, (1, 100, 1)))
    assert sealer.open_hello(forged, 9) is None
    assert sealer.bad.counts == {secoc.HELLO_UNKEYED: 1}
