"""Links by URL: the registry, option checking, the error tree, and
`touchswarm run --link can` equal to `--link inproc`."""

import json

import can
import pytest

from bridge.cli import main
from bridge.errors import BridgeError, UsageError
from bridge.links import (LinkError, LinkTimeoutError, LinkURLError, REGISTRY, open_bus,
                          parse_url)
from bridge.links.canlink import CanLink, Faults
from sim_backend import scenario
from sim_backend.engine import Engine


def test_error_tree():
    assert issubclass(LinkError, BridgeError)
    # the two kinds a caller tells apart: a timeout, a malformed URL (exit 2)
    assert issubclass(LinkTimeoutError, LinkError) and issubclass(LinkTimeoutError, TimeoutError)
    assert issubclass(LinkURLError, UsageError) and issubclass(LinkURLError, LinkError)


@pytest.mark.parametrize("url,want", [
    ("virtual://bench", ("virtual", "bench", {})),
    ("socketcan://can0", ("socketcan", "can0", {})),
    ("slcan:///dev/ttyACM0?bitrate=500000", ("slcan", "/dev/ttyACM0", {"bitrate": 500000})),
    ("slcan:///dev/pts/3?bitrate=1000000&baud=921600",
     ("slcan", "/dev/pts/3", {"bitrate": 1000000, "baud": 921600})),
    ("can://pcan/PCAN_USBBUS1?bitrate=250000", ("can", "pcan/PCAN_USBBUS1", {"bitrate": 250000})),
])
def test_parse_url(url, want):
    assert parse_url(url) == want


@pytest.mark.parametrize("url,words", [
    ("virtual://x?bitrate=5", ["unknown option 'bitrate'", "virtual://CHANNEL"]),
    ("slcan:///dev/ttyACM0?speed=5", ["unknown option 'speed'", "bitrate", "slcan:///dev/ttyACM0"]),
    ("slcan:///dev/ttyACM0?bitrate=fast", ["not an integer"]),
    ("can://pcan?bitrate=5", ["missing channel", "can://INTERFACE/CHANNEL"]),
    ("bogus://x", ["unknown link", "virtual://CHANNEL"]),
    ("virtual://", ["missing channel"]),
])
def test_bad_urls_name_the_expected_form(url, words):
    with pytest.raises(LinkURLError) as e:
        parse_url(url)
    for w in words:
        assert w in str(e.value)


def test_registry_is_lazy_and_open_errors_are_converted(tmp_path):
    for target in REGISTRY.values():
        assert ":" in target
    with open_bus("virtual://t-links") as a, open_bus("virtual://t-links") as b:
        a.send(can.Message(arbitration_id=0x201, data=b"\x01", is_extended_id=False))
        assert b.recv(1.0).arbitration_id == 0x201
    with pytest.raises(LinkError, match="cannot open slcan://"):
        open_bus(f"slcan://{tmp_path}/no-such-tty")
    with pytest.raises(LinkError, match="udp_multicast"):
        open_bus("can://udp_multicast/239.0.0.1")


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5])
def test_run_over_can_equals_inproc(seed, capsys):
    outs = {}
    for link in ("inproc", "can"):
        main(["run", "--seed", str(seed), "--link", link, "--json"])
        outs[link] = json.loads(capsys.readouterr().out)
    assert outs["can"] == outs["inproc"]
    assert outs["can"]["delivered"]


def test_run_over_can_equals_inproc_ant():
    sc = scenario.load("ant").replace(agents=12)
    a = Engine(sc, 9).run().summary()
    with CanLink(list(range(1, 13))) as link:
        b = Engine(sc, 9, link=link).run().summary()
        assert link.frames_up > 0 and link.frames_down > 0 and link.bad_frames() == {}
    assert a == b


def test_canlink_close_is_idempotent():
    link = CanLink([1, 2])
    link.close()
    link.close()


def test_faults_are_seeded_and_bounded():
    f1, f2 = Faults(3, loss=0.2, dup=0.1, window=4), Faults(3, loss=0.2, dup=0.1, window=4)
    frames = list(range(1000))
    a, b = f1.apply(frames), f2.apply(frames)
    assert a == b
    assert 700 < len(a) < 950 and f1.dropped > 100 and f1.duplicated > 50
    # reordering stays within the window
    assert a != sorted(a)
    with pytest.raises(ValueError):
        Faults(loss=1.0)


def test_cli_rejects_bad_url(capsys):
    assert main(["host", "--bus", "virtual://x?foo=1"]) == 2
    assert "unknown option 'foo'" in capsys.readouterr().err
    assert main(["robots", "--bus", "slcan:///dev/ttyACM0?speed=1"]) == 2
    assert "expected slcan:///dev/ttyACM0" in capsys.readouterr().err


def test_slcan_pty_face_speaks_slcan(tmp_path):
    path = tmp_path / "ada"
    with open_bus(f"slcan-pty://{path}") as robots:
        assert path.is_symlink()
        with open_bus(f"slcan://{path}?bitrate=500000&settle_ms=0") as host:
            robots.recv(0.05)          # the adapter takes the host's C / S6 / O
            assert robots.bitrate == 500000 and robots.is_open
            robots.send(can.Message(arbitration_id=0x201, data=b"\x01\x02", is_extended_id=False))
            m = host.recv(2.0)
            assert (m.arbitration_id, bytes(m.data)) == (0x201, b"\x01\x02")
            host.send(can.Message(arbitration_id=0x181, data=b"\x05", is_extended_id=False))
            m = robots.recv(2.0)
            assert (m.arbitration_id, bytes(m.data)) == (0x181, b"\x05")
    assert not path.exists()
