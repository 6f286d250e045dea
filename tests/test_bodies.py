"""Body URLs (bridge/bodies) and the `touchswarm mission` command's bad input.

Every bad URL is one typed error line naming what was wrong; the CLI exits 2
before any device is driven. The missions themselves run end to end in
hil_tests/test_mixed_mission.py.
"""

from __future__ import annotations

import pytest

from bridge import bodies
from bridge.bodies import BodyURLError, parse_assignment, parse_body_url
from bridge.cli import main as cli_main
from bridge.errors import UsageError


def test_every_registered_kind_has_a_module_an_example_and_options() -> None:
    import importlib
    assert set(bodies.REGISTRY) == set(bodies.EXPECTED) == set(bodies.OPTIONS) \
        == {"sim", "khepera", "gogo", "mpy"}
    for scheme, target in bodies.REGISTRY.items():
        modname, _, func = target.partition(":")
        assert callable(getattr(importlib.import_module(modname), func)), scheme
        assert bodies.EXPECTED[scheme].startswith(scheme + "://")


@pytest.mark.parametrize("url, scheme, port, options", [
    ("sim://", "sim", "", {}),
    ("khepera://loop://", "khepera", "loop://", {}),
    ("khepera:///dev/null?baud=38400", "khepera", "/dev/null", {"baud": 38400}),
    ("khepera://loop://?baud=9600&x=-3&y=2.5&heading=90&patch_mm=40", "khepera", "loop://",
     {"baud": 9600, "x": -3.0, "y": 2.5, "heading": 90.0, "patch_mm": 40.0}),
    ("gogo://socket://127.0.0.1:7777?mm_s_per_level=18&wheel_base_mm=95", "gogo",
     "socket://127.0.0.1:7777", {"mm_s_per_level": 18.0, "wheel_base_mm": 95.0}),
    ("mpy:///dev/null", "mpy", "/dev/null", {}),
])
def test_good_urls_parse(url: str, scheme: str, port: str, options: dict) -> None:
    spec = parse_body_url(url)
    assert (spec.scheme, spec.port, spec.options) == (scheme, port, options)


@pytest.mark.parametrize("url, needle", [
    ("foo:///dev/ttyUSB0", "unknown kind 'foo'"),
    ("/dev/ttyUSB0", "expected SCHEME://PORT"),
    ("khepera://", "missing port"),
    ("gogo://?baud=9600", "missing port"),
    ("khepera:///dev/ttyUSB0?speed=9600", "unknown option 'speed'"),
    ("khepera://loop://?baud=fast", "baud='fast' is not an integer"),
    ("khepera://loop://?baud=1200", "one of 9600, 19200, 38400, 57600, 115200"),
    ("gogo://loop://?baud=0", "must be positive"),
    ("khepera://loop://?x=west", "x='west' is not a number"),
    ("khepera://loop://?patch_mm=-5", "patch_mm=-5.0 must be positive"),
    ("khepera://loop://?baud=9600&baud=38400", "given twice"),
    ("sim:///dev/ttyUSB0", "sim:// takes no port"),
    ("khepera:///dev/ttyUSB97", "no such device '/dev/ttyUSB97'"),
    ("mpy:///dev/ttyACM97", "no such device '/dev/ttyACM97'"),
])
def test_bad_urls_are_one_typed_line(url: str, needle: str) -> None:
    with pytest.raises(BodyURLError) as err:
        parse_body_url(url)
    assert isinstance(err.value, UsageError)
    assert needle in str(err.value) and "\n" not in str(err.value)


def test_assignment() -> None:
    node, spec = parse_assignment("3=khepera://loop://")
    assert node == 3 and spec.scheme == "khepera"
    for bad, needle in (("khepera://loop://", "expected NODE=URL"),
                        ("x=sim://", "node 'x' is not a number"), ("3=", "expected NODE=URL")):
        with pytest.raises(BodyURLError, match=needle):
            parse_assignment(bad)


@pytest.mark.parametrize("args, needle", [
    (["--body", "1=foo://x"], "unknown kind 'foo'"),
    (["--body", "1=khepera:///dev/ttyUSB97"], "no such device '/dev/ttyUSB97'"),
    (["--body", "1=khepera://loop://?bogus=1"], "unknown option 'bogus'"),
    (["--body", "1=sim://", "--body", "1=sim://"], "given twice"),
    (["--body", "99=sim://"], "node 99 is not a robot of the scenario (1..20)"),
    (["--body", "1=sim://", "--robots", "200"], "do not fit the serial link"),
    # a port that is there but answers nothing a Khepera would: refused before the run
    (["--body", "1=khepera://loop://"], "did not answer 'B'"),
    (["--body", "1=gogo:///dev/null"], "cannot open serial port '/dev/null'"),
])
def test_mission_bad_input_exits_2_with_one_line(args: list[str], needle: str, capsys) -> None:
    assert cli_main(["mission", *args]) == 2
    err = capsys.readouterr().err
    assert needle in err, err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1


def test_mission_help_lists_the_body_urls(capsys) -> None:
    with pytest.raises(SystemExit):
        cli_main(["mission", "--help"])
    out = capsys.readouterr().out
    for form in ("sim://", "khepera:///dev/ttyUSB0?baud=38400", "gogo:///dev/ttyUSB1", "x=",
                 "docs/serial.md"):
        assert form in out


def test_an_all_simulated_mission_runs_like_run(capsys) -> None:
    # sim:// bodies change nothing: the same run as `touchswarm run`
    assert cli_main(["run", "--json", "--robots", "8", "--seed", "4"]) == 0
    import json
    ran = json.loads(capsys.readouterr().out)
    assert cli_main(["mission", "--json", "--robots", "8", "--seed", "4", "--body", "2=sim://",
                     "--tick-ms", "0.001"]) == 0
    mixed = json.loads(capsys.readouterr().out)
    assert mixed["bodies"] == {"2": "simulated"} and mixed["real_touches"] == {}
    for key in ("touches", "segments", "home_tick", "converged_tick", "ticks"):
        assert mixed[key] == ran[key], key
