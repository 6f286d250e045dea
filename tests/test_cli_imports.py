"""The command line imports only what the chosen command uses:
`--version` and `--help` build no command's parser, and `run`
never loads the CAN, compiler, serial or columnar packages. Checked by
what is in sys.modules after the command, in a fresh interpreter: no
timing."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from bridge import cli, cli_parser

ROOT = Path(__file__).resolve().parents[1]

HEAVY = ("numpy", "matplotlib", "numba", "can", "cantools", "serial", "pyarrow", "pandas")
# what `touchswarm run` may never need (numpy it does need: the engine)
NOT_FOR_RUN = ("matplotlib", "numba", "llvmlite", "can", "cantools", "serial", "pyarrow",
               "pandas", "PIL")
# standard modules a run of a built-in behaviour without output files never
# uses (whole modules, not packages): installed packages' metadata (their
# entry points; a built-in is found without them) and the email and zipfile
# modules it loads, package resources, temporary files, child processes,
# digests, sockets; shutil (argparse's terminal width, asked only to print
# help) and the compression modules it loads; logging (nothing of a plain
# run logs unless -v asks: perception.detail); tomllib (a built-in
# scenario and plain --set values are flat: scenario.flat_toml)
STDLIB_NOT_FOR_RUN = ("importlib.metadata", "importlib.resources", "email", "zipfile",
                      "tempfile", "subprocess", "hashlib", "socket", "shutil", "bz2", "lzma",
                      "logging", "tomllib")

PROBE = """
import contextlib, io, json, sys
import bridge.cli
out = io.StringIO()
with contextlib.redirect_stdout(out):
    try:
        code = bridge.cli.main(json.loads(sys.argv[1]))
    except SystemExit as e:
        code = e.code
print(json.dumps({"code": code, "out": out.getvalue(), "modules": sorted(sys.modules)}))
"""


def probe(*argv: str) -> dict:
    """Run bridge.cli.main(argv) in a fresh interpreter: its exit code, stdout
    and every module it imported."""
    done = subprocess.run([sys.executable, "-c", PROBE, json.dumps(argv)], cwd=ROOT,
                          capture_output=True, text=True, timeout=300, check=True)
    return json.loads(done.stdout.splitlines()[-1])


def loaded(modules: list[str], packages: tuple[str, ...]) -> list[str]:
    return sorted({m.split(".")[0] for m in modules} & set(packages))


def commands(modules: list[str]) -> list[str]:
    """The command modules among `modules`."""
    mods = {m for m, _help in cli.COMMANDS.values()}
    return sorted(m for m in modules if m in mods)


def test_version_imports_no_command_and_no_heavy_package():
    got = probe("--version")
    assert got["code"] == 0 and got["out"].startswith("touchswarm ")
    assert loaded(got["modules"], HEAVY) == []
    assert commands(got["modules"]) == []


def test_version_alone_needs_no_parser_and_no_metadata_library():
    got = probe("--version")
    from importlib.metadata import version
    assert got["code"] == 0 and got["out"] == f"touchswarm {version('touchswarm')}\n"
    assert [m for m in ("argparse", "importlib.metadata", "sim_backend.api", "logging")
            if m in got["modules"]] == []


@pytest.mark.parametrize("layout", [
    {"a": {"touchswarm-9.1.dist-info": ("METADATA", "9.1")}},
    {"a": {"TouchSwarm-9.2.dist-info": ("METADATA", "9.2")}},
    # the first folder on the path decides, of either form
    {"a": {"touchswarm.egg-info": ("PKG-INFO", "9.3")},
     "b": {"touchswarm-9.4.dist-info": ("METADATA", "9.4")}},
    {"a": {"touch_swarm-1.0.dist-info": ("METADATA", "1.0"), "other-2.0.dist-info":
           ("METADATA", "2.0")}, "b": {"touchswarm-9.5.dist-info": ("METADATA", "9.5")}},
])
def test_the_version_is_what_importlib_metadata_reads(tmp_path, monkeypatch, layout):
    """sim_backend.version reads the metadata file importlib.metadata would
    (without importing it) for installs as wheels, editable or not."""
    from importlib.metadata import version as dist_version

    from sim_backend import version
    for entry, folders in layout.items():
        for folder, (name, number) in folders.items():
            (tmp_path / entry / folder).mkdir(parents=True)
            (tmp_path / entry / folder / name).write_text(
                f"Metadata-Version: 2.1\nName: x\nVersion: {number}\n\nVersion: 0.0\n")
    monkeypatch.setattr(sys, "path", [str(tmp_path / e) for e in layout])
    assert version._from_info_folder() == dist_version("touchswarm")
    assert version.version() == dist_version("touchswarm")


def test_help_lists_every_command_without_building_one():
    got = probe("--help")
    assert got["code"] == 0
    for name, (_module, help) in cli.COMMANDS.items():
        assert f"\n    {name} " in got["out"], name
        assert help.split()[0] in got["out"]
    assert loaded(got["modules"], HEAVY) == []
    assert commands(got["modules"]) == []


def test_help_loads_no_typing_nor_shutil_and_its_compressors():
    got = probe("--help")
    assert got["code"] == 0
    assert [m for m in ("typing", "shutil", "bz2", "lzma", "zlib", "logging", "dataclasses",
                        "sim_backend") if m in got["modules"]] == []


@pytest.mark.parametrize("columns", [None, "", "0", "-3", "x", "57", "131"])
def test_the_terminal_width_is_shutils(monkeypatch, columns):
    import shutil
    if columns is None:
        monkeypatch.delenv("COLUMNS", raising=False)
    else:
        monkeypatch.setenv("COLUMNS", columns)
    assert cli_parser.terminal_columns() == shutil.get_terminal_size().columns


def test_run_help_builds_only_run():
    got = probe("run", "--help")
    assert got["code"] == 0 and "--animate FILE" in got["out"]
    from sim_backend.animate import MAX_FRAMES
    assert f"at most {MAX_FRAMES} frames" in " ".join(got["out"].split())
    assert loaded(got["modules"], NOT_FOR_RUN) == []
    assert commands(got["modules"]) == ["bridge.commands.run"]


def test_a_run_loads_no_can_compiler_serial_plot_or_parquet_package():
    got = probe("run", "--json", "--set", "maxTicks=40")
    assert got["code"] in (0, 1)
    assert json.loads(got["out"])["ticks"] <= 40
    assert loaded(got["modules"], NOT_FOR_RUN) == []
    assert commands(got["modules"]) == ["bridge.commands.run"]
    assert sorted(set(got["modules"]) & set(STDLIB_NOT_FOR_RUN)) == []
    assert "sim_backend.animate" not in got["modules"]     # read by --animate and its help only


def test_a_text_run_imports_no_json_and_prints_its_summary():
    """json (5 M instructions of patterns compiled at import) only for --json."""
    script = ("import contextlib, io, sys\nimport bridge.cli\nout = io.StringIO()\n"
              "with contextlib.redirect_stdout(out):\n"
              "    code = bridge.cli.main(['run', '--set', 'maxTicks=40'])\n"
              "print(code, 'json' in sys.modules, 'bridge.commands.run' in sys.modules)\n"
              "print(out.getvalue())")
    # (the suite's record of command lines, TOUCHSWARM_ARGV_LOG, is JSON)
    env = {k: v for k, v in os.environ.items() if k != "TOUCHSWARM_ARGV_LOG"}
    done = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True,
                          text=True, timeout=300, check=True, env=env)
    status, out = done.stdout.split("\n", 1)
    assert status in ("0 False True", "1 False True")
    assert out.startswith("scenario default: 20 ") and "  result " in out


def test_a_verbose_run_still_logs_what_it_recognised():
    """-v configures logging before the run: the tracker's INFO record is one
    line naming its logger, as before the plain run stopped importing logging."""
    done = subprocess.run([sys.executable, "-m", "bridge.cli", "-v", "run", "--json", "--set",
                           "maxTicks=200"], cwd=ROOT, capture_output=True, text=True,
                          timeout=300)
    assert done.returncode == 0
    assert done.stderr.startswith("INFO perception.tracker: recognised bar (p ")


def test_a_sweep_without_a_preset_loads_no_plotting_module(tmp_path):
    """--no-plots on the reference engine: no figure module, no compiler."""
    got = probe("sweep", "--seeds", "2", "--engine", "reference", "--executor", "inline",
                "--no-plots", "--json", "--set", "maxTicks=30", "--out", str(tmp_path / "s"))
    assert got["code"] == 0
    assert [m for m in got["modules"] if m in ("sim_backend.plots", "sim_backend.arena_presets",
                                              "sim_backend.robustness")] == []
    assert loaded(got["modules"], NOT_FOR_RUN) == []


def test_importing_the_facade_reads_the_version_only_when_asked():
    code = ("import importlib, json, sys, touchswarm; "
            "before = 'importlib.metadata' in sys.modules; "
            "print(json.dumps([before, touchswarm.__version__, "
            "importlib.import_module('importlib.metadata').version('touchswarm')]))")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=300, check=True)
    before, version, installed = json.loads(done.stdout)
    assert before is False and version == installed


def test_no_command_parser_needs_a_heavy_package():
    """Every command's --help (all parsers built, as for docs/cli.md) loads
    none of them: heavy imports are inside the handlers."""
    code = ("import json, sys; from bridge.cli_parser import build_parser; build_parser(full=True); "
            "print(json.dumps(sorted(sys.modules)))")
    done = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True,
                          text=True, timeout=300, check=True)
    assert loaded(json.loads(done.stdout), NOT_FOR_RUN) == []


def test_help_still_wraps_at_the_terminal_width(monkeypatch):
    """add_argument's metavar check formats with a fixed width (no shutil on
    a run); the help a user reads keeps the terminal's."""
    sub = next(a for a in cli_parser.build_parser()._actions if isinstance(a, cli_parser.LazyCommands))
    sub.load("run")
    for columns in (50, 120):
        monkeypatch.setenv("COLUMNS", str(columns))
        text = sub.choices["run"].format_help()     # options: wrapped (the epilog is raw)
        lines = text[text.index("\noptions:"):text.index("\nexamples:")].splitlines()
        assert max(map(len, lines)) <= columns - 2
        assert max(map(len, lines)) > columns - 12


def test_the_lazy_help_is_the_full_help():
    """`touchswarm --help` from the table alone equals the help with every
    command's parser built (the one-line helps are written once, in COMMANDS)."""
    assert cli_parser.build_parser().format_help() == cli_parser.build_parser(full=True).format_help()


def test_every_command_in_the_table_is_built_by_its_module():
    p = cli_parser.build_parser(full=True)
    sub = next(a for a in p._actions if isinstance(a, cli_parser.LazyCommands))
    assert list(sub.choices) == list(cli.COMMANDS)
    for name, parser in sub.choices.items():
        assert parser is not None and parser.prog == f"touchswarm {name}"


def test_a_command_module_may_not_write_its_own_help_or_an_unlisted_name():
    sub = next(a for a in cli_parser.build_parser()._actions if isinstance(a, cli_parser.LazyCommands))
    with pytest.raises(ValueError, match="COMMANDS"):
        sub.add_parser("run", help="a second one-line help")
    with pytest.raises(ValueError, match="not in bridge/cli.py COMMANDS"):
        sub.add_parser("frobnicate")


def test_a_parse_builds_the_named_command_only():
    p = cli_parser.build_parser()
    sub = next(a for a in p._actions if isinstance(a, cli_parser.LazyCommands))
    args = p.parse_args(["scenarios"])
    assert args.command == "scenarios" and args.func
    built = [name for name, parser in sub.choices.items() if parser is not None]
    assert built == ["scenarios"]


def test_an_unknown_command_is_one_line_naming_the_choices():
    done = subprocess.run([sys.executable, "-m", "bridge.cli", "frobnicate"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.count("\n") == 1
    assert "invalid choice: 'frobnicate'" in done.stderr and "'run'" in done.stderr


def test_firmware_cli_alone_is_touchswarm_firmware():
    done = subprocess.run([sys.executable, "-m", "bridge.firmware.cli", "--help"], cwd=ROOT,
                          capture_output=True, text=True, timeout=120)
    assert done.returncode == 0 and done.stdout.startswith("usage: touchswarm firmware ")


def test_the_start_up_bench_runs_and_reports_every_command():
    """bench/cli_startup.py (docs/performance.md, `make bench`) as written;
    its figures are read, not asserted."""
    done = subprocess.run([sys.executable, "bench/cli_startup.py", "--reps", "1", "--tree",
                           str(ROOT)], cwd=ROOT, capture_output=True, text=True, timeout=300,
                          check=True)
    got = json.loads(done.stdout)
    for name in ("--version", "--help", "run --json"):
        for tree in ("this", str(ROOT)):
            assert f"{tree}: touchswarm {name}" in got["seconds"]
            assert got["imports"][f"{tree}: touchswarm {name}"]["modules"] > 0
    assert "python -c 'import numpy'" in got["seconds"]


# valgrind's summary line, with a count the bench's arithmetic can be checked
# by: 100 M, +300 M for `import numpy`, +10 M for each call of main
FAKE_VALGRIND = """#!{python}
import sys
text = " ".join(sys.argv)
n = 100_000_000 + 300_000_000 * text.count("import numpy") + 10_000_000 * text.count("main(")
print(f"==1== I   refs:      {{n:,}}", file=sys.stderr)
"""


def test_the_bench_counts_instructions_as_valgrind_reports_them(tmp_path, monkeypatch):
    """--instructions reads cachegrind's I refs line; the run's floor is
    import numpy plus the second of two runs in one process."""
    tool = tmp_path / "valgrind"
    tool.write_text(FAKE_VALGRIND.format(python=sys.executable))
    tool.chmod(0o755)
    monkeypatch.syspath_prepend(str(ROOT / "bench"))
    import cli_startup
    monkeypatch.setitem(cli_startup.ENV, "PATH", f"{tmp_path}{os.pathsep}{os.environ['PATH']}")
    got = cli_startup.count_instructions({"this": ROOT})
    assert got["python -c pass"] == 100.0 and got["python -c 'import numpy'"] == 400.0
    assert got["this: touchswarm run --json"] == 110.0 and got["this: run in process"] == 10.0
    assert got["this: run --json over its floor"] == round(110 / (400 + 10), 4)


FLAT = ['a = 1', 'a=-0', 'a = +7 # c', 'a = 0.50', 'a = "x # y" # z', 'a = true\r\nb = false',
        'k_-9 = "\u00e9"', '# only\n\n\t', 'a = ""', '1 = 2']
NOT_FLAT = ['a = 01', 'a = 1_000', 'a = 1e3', 'a = .5', 'a = 5.', "a = 'x'", 'a = "x\\ty"',
            'a = 1\na = 2', '[t]\na = 1', 'a.b = 1', 'a = "x" y', 'a = [1]', 'a = inf',
            'a = \u0661', 'a = 1\rb = 2', 'a = "\x01"', 'a = +-1', 'a = """x"""']


@pytest.mark.parametrize("text", FLAT + NOT_FLAT)
def test_the_flat_reader_reads_what_tomllib_reads_or_leaves_it(text):
    """scenario.flat_toml (a run's scenario without tomllib's import) gives
    tomllib's table, types included, or None: tomllib reads it then."""
    import tomllib

    from sim_backend.scenario import flat_toml
    got = flat_toml(text)
    assert (got is not None) == (text in FLAT)
    if got is not None:
        want = tomllib.loads(text)
        assert got == want and [type(v) for v in got.values()] == [type(v) for v in want.values()]


def test_the_flat_reader_agrees_with_tomllib_on_every_built_in_and_random_texts():
    import random
    import tomllib

    from sim_backend.scenario import SCENARIOS_DIR, flat_toml
    texts = [p.read_text(encoding="utf-8") for p in sorted(SCENARIOS_DIR.glob("*.toml"))]
    assert flat_toml(texts[[p.name for p in sorted(SCENARIOS_DIR.glob("*.toml"))]
                           .index("default.toml")]) is not None
    bits = ["a", "1", "0", "=", " ", '"', "#", ".", "-", "+", "\n", "\t", "\\", "true",
            "[", "_", "e", "'", "\r", "9"]
    rnd = random.Random(28)
    texts += ["".join(rnd.choice(bits) for _ in range(rnd.randint(1, 12))) for _ in range(20000)]
    read = 0
    for text in texts:
        got = flat_toml(text)
        if got is None:
            continue
        read += 1
        want = tomllib.loads(text)      # raises if flat_toml took an invalid text
        assert got == want and [type(v) for v in got.values()] == \
            [type(v) for v in want.values()], repr(text)
    assert read > 500


def test_the_scenario_behaves_as_the_frozen_dataclass_it_was():
    """Scenario's hand-written methods (no generated ones to compile at
    import) keep the frozen dataclass's behaviour: keyword construction with
    defaults, equality and hash over the fields, a frozen instance, the
    dataclasses functions, pickling, and the repr."""
    import dataclasses
    import pickle

    from sim_backend.scenario import Scenario, load
    a, b = Scenario(), Scenario(agents=5)
    assert a == Scenario() and hash(a) == hash(Scenario()) and a != b and a != 5
    assert b.agents == 5 and b.worldSize == 18 and a.params == b.params != ()
    with pytest.raises(dataclasses.FrozenInstanceError):
        a.agents = 3
    with pytest.raises(dataclasses.FrozenInstanceError):
        del a.agents
    with pytest.raises(TypeError, match="unexpected keyword argument 'agentz'"):
        Scenario(agentz=3)
    names = [f.name for f in dataclasses.fields(Scenario)]
    assert names[:3] == ["name", "description", "agents"] and names[-1] == "params"
    assert list(Scenario.__dataclass_fields__) == names
    assert dataclasses.replace(a, agents=7) == Scenario(agents=7)
    assert list(dataclasses.asdict(a)) == names
    ant = load("ant")
    assert pickle.loads(pickle.dumps(ant)) == ant and ant.robotVisionSpan == ant.params[1][1]
    assert repr(b).startswith("Scenario(name='default', description='', agents=5, sigRadius=5, ")
    assert repr(b).endswith(f"breeds=(), params={b.params!r})")
    assert {a: 1}[Scenario()] == 1


def test_the_home_distance_check_refuses_what_trying_every_anchor_refused():
    """scenario._check_consistency takes each cell's nearest anchor to home
    instead of trying all: the same scenarios refused, on 400 random homes,
    objects and anchors against the check that tried every anchor."""
    import random

    from sim_backend import objects
    from sim_backend.errors import ScenarioError
    from sim_backend.scenario import validate
    rng = random.Random(7)
    refused = 0
    for _ in range(400):
        shape = rng.choice(sorted(objects.SHAPES))
        keys = {"object": shape, "homeX": rng.randint(-15, 15), "homeY": rng.randint(-15, 15)}
        if rng.random() < 0.5:
            keys.update(objectX=rng.randint(-8, 8), objectY=rng.randint(-8, 8))
        ax = [keys["objectX"]] * 2 if "objectX" in keys else [0, 9]
        ay = [keys["objectY"]] * 2 if "objectY" in keys else [0, 9]
        near = any((x + ox - keys["homeX"]) ** 2 + (y + oy - keys["homeY"]) ** 2 < 16
                   for x, y in objects.offsets(shape)
                   for ox in range(ax[0], ax[1] + 1) for oy in range(ay[0], ay[1] + 1))
        try:
            validate(keys)
            said = False
        except ScenarioError as err:
            said = "within 4 patches of home" in str(err)
            if "does not fit the arena" in str(err):
                continue            # refused before the home check
        assert said == near, keys
        refused += said
    assert 20 < refused < 380
