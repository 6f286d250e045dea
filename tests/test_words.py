"""A run's outputs speak its behaviour's words
(sim_backend/words.py): the text summary, world.png, the GIF's titles and
the sweep plots show the behaviour's MEASURES and REPORTERS with their
titles; the thesis's words (power, weight, shape IoU, touches that hold
the object) appear only for the thesis, which declares them in its spec.py.
The live view's side is in tests/test_view.py."""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")

from bridge.cli import main  # noqa: E402
from sim_backend import registry  # noqa: E402
from sim_backend import plots, scenario, sweep, words  # noqa: E402

# words only the thesis may say (its spec.py HEADER, SUMMARY, RESULT, SHAPE, LOAD, PLOTS)
THESIS_WORDS = ("power", "weight", "IoU", "perceived", "hold the object", "DELIVERED",
                "delivered home", "convergence", "delivery")


def no_thesis_words(text: str) -> None:
    for word in THESIS_WORDS:
        assert word not in text, f"{word!r} in {text!r}"


def figure_texts(fig) -> str:
    """Every text a figure draws: titles, labels, legends, tick labels."""
    from matplotlib.text import Text
    return "\n".join(t.get_text() for t in fig.findobj(Text))


def titles(behaviour) -> list[str]:
    b = registry.load(behaviour)
    return [t for _, t in b.spec.MEASURES] + [t for _, t in getattr(b.spec, "REPORTERS", ())]


@pytest.fixture(scope="module")
def tiny(tmp_path_factory) -> Path:
    """A behaviour from the scaffold, outside the repo, with measure titles of its own."""
    into = tmp_path_factory.mktemp("mine")
    assert main(["behaviour", "new", "tiny", "--into", str(into)]) == 0
    spec = into / "tiny" / "spec.py"
    text = spec.read_text()
    for old, new in (("robots that stopped", "robots resting in a heap"),
                     ("robots in the largest cluster", "robots in the biggest heap")):
        assert old in text
        text = text.replace(old, new)
    spec.write_text(text)
    return into / "tiny"


# -- the text summary ------------------------------------------------------------------


@pytest.mark.parametrize("which", ["aggregate", "tiny"])
def test_the_summary_says_the_behaviours_measures_and_no_thesis_word(which, tiny, capsys):
    behaviour = str(tiny) if which == "tiny" else which
    assert main(["run", "--behaviour", behaviour]) == 0       # quorum reached
    out = capsys.readouterr().out
    for title in titles(behaviour):
        assert title in out
    assert re.search(r"robots that stopped +\d+" if which == "aggregate"
                     else r"robots resting in a heap +\d+", out)
    assert re.search(r"tick the first robot stopped +tick \d+", out)
    assert "DONE after" in out and f"behaviour {registry.load(behaviour).name}" in out
    no_thesis_words(out)


def test_the_thesis_summary_keeps_its_own_words(capsys):
    main(["run", "--set", "maxTicks=400"])
    out = capsys.readouterr().out
    assert "robots hold the object, power" in out and "shape IoU" in out
    assert re.search(r"converged +tick \d+  \(power [\d.]+ held then\)", out)
    assert "firefly robots, object bar" in out


def test_a_summary_line_whose_values_the_run_lacks_is_left_out():
    b = registry.load("aggregate")
    lines = words.summary_lines(b, {"scenario": "s", "robots": 3, "seed": 1, "stopped": 2})
    assert lines[0] == "scenario s: 3 robots, behaviour aggregate, seed 1"
    assert [ln.split()[-1] for ln in lines[1:]] == ["2"]     # only `stopped` was given
    assert words.fill("{found_tick!t} / {n!n}", {"found_tick": None, "n": [1, 2]}) \
        == "never / 2"


# -- world.png and the GIF -------------------------------------------------------------


def test_world_png_shows_the_measures_and_no_shape_panel(tiny, tmp_path):
    from sim_backend.engine import Engine
    from sim_backend.observe import Trails
    from sim_backend.render import figure, render
    for behaviour in ("aggregate", str(tiny)):
        engine = Engine(scenario.load("default").replace(behaviour=behaviour), 1)
        trails = Trails(engine)
        result = engine.run()
        fig = figure(result, trails)
        text = figure_texts(fig)
        for title in titles(behaviour):
            assert title in text
        assert re.search(r"robots (that stopped|resting in a heap): \d+", text)
        no_thesis_words(text)
        path = render(result, tmp_path / "world.png", trails)
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_world_png_of_the_thesis_has_its_perceived_vs_true_panel():
    from sim_backend.engine import Engine
    from sim_backend.render import figure
    result = Engine(scenario.load("default").replace(maxTicks=300), 1).run()
    text = figure_texts(figure(result))
    assert "hull (blue outline" in text and "shape IoU" in text


def test_the_gif_titles_are_the_tick_and_the_reporters(tmp_path):
    from sim_backend.animate import Animation
    from sim_backend.engine import Engine
    from sim_backend.observe import Trails
    engine = Engine(scenario.load("default").replace(behaviour="aggregate", maxTicks=30), 1)
    anim = Animation(engine, Trails(engine), every=10)
    engine.run()
    drawn: list[tuple[int, int]] = []
    assert anim.write(tmp_path / "run.gif", progress=lambda *a: drawn.append(a)) == 4
    assert drawn == [(1, 4), (2, 4), (3, 4), (4, 4)]        # --animate's progress bar
    title = anim.title(anim.frames[-1])
    assert re.fullmatch(r"tick 30: .+\nstopped \d+, clusters \d+, largest \d+", title)
    assert "weight" not in title
    thesis = Engine(scenario.load("default").replace(maxTicks=30), 1)
    anim = Animation(thesis, Trails(thesis), every=10)
    thesis.run()
    anim.finish()
    # the phase, the load (power of weight), the reporters and the shape's score
    assert re.fullmatch(r"tick 30: collecting touches, power [\d.]+ of weight 5\.00\n"
                        r"power [\d.]+ of weight 5\.00, holders \d+, home_d2 -?\d+, "
                        r"shape IoU [\d.]+", anim.title(anim.frames[-1]))


# -- the sweep plots: one panel per declared measure -----------------------------------


def test_sweep_plots_of_aggregation_have_one_panel_per_measure(tmp_path):
    base = scenario.load("default").replace(behaviour="aggregate")
    rows = sweep.sweep(sweep.grid_points({"quorum": [50, 80]}), [1, 2], base=base,
                       engine="reference")
    fig = plots.factor_figure(rows, "quorum", [])
    spec = registry.load("aggregate").spec
    assert [ax.get_title().replace("\n", " ") for ax in fig.axes] \
        == [t for _, t in spec.MEASURES]
    no_thesis_words(figure_texts(fig))
    paths = plots.grid_plots(rows, ["quorum"], tmp_path)
    assert [p.name for p in paths] == ["by_quorum.png"] and paths[0].stat().st_size > 1000


def test_sweep_plots_of_the_thesis_are_its_declared_plots():
    rows = [{"experiment": "grid", "maxTicks": "300", "fieldDefiance": str(d), "seed": str(s),
             "converged_tick": str(100 + s), "delivered": "True", "shape_iou": "0.5"}
            for d in (1, 2) for s in (1, 2)]
    fig = plots.factor_figure(rows, "fieldDefiance", [])
    assert [ax.get_title() for ax in fig.axes] == ["convergence tick", "delivery rate",
                                                   "shape IoU"]


# -- the documented commands (docs/outputs.md "The behaviour's words",
# docs/writing-a-behaviour.md "Its words") run as written ----------------------------

ROOT = Path(__file__).resolve().parent.parent


def doc_commands(doc: str, heading: str) -> list[str]:
    """The `sh` fenced commands of one section of a doc, comments dropped."""
    text = (ROOT / "docs" / doc).read_text()
    m = re.search(rf"^## {re.escape(heading)}$(.*?)(?=^## |\Z)", text, re.M | re.S)
    assert m, f"docs/{doc} has no section '## {heading}'"
    blocks = re.findall(r"```sh\n(.*?)```", m.group(1), re.S)
    return [line.split("#")[0].strip() for b in blocks for line in b.splitlines()
            if line.split("#")[0].strip()]


@pytest.mark.parametrize("doc, heading", [("outputs.md", "The behaviour's words"),
                                          ("writing-a-behaviour.md", "Its words")])
def test_the_documented_commands_run(doc, heading, tmp_path, capsys):
    import shlex
    cmds = doc_commands(doc, heading)
    assert len(cmds) == 2
    for cmd in cmds:
        argv = shlex.split(cmd.replace("/tmp", str(tmp_path)))
        assert argv[0] == "touchswarm"
        assert main(argv[1:]) == 0, cmd
    out = capsys.readouterr().out
    if doc == "outputs.md":
        # the two summaries the section shows, as the runs print them
        section = (ROOT / "docs" / doc).read_text().split("## The behaviour's words")[1]
        shown = re.findall(r"```text\n(.*?)```", section.split("\n## ")[0], re.S)
        for block in shown:
            for line in block.splitlines():
                if line.strip() != "...":
                    assert line in out.splitlines(), line
    else:
        no_thesis_words(out.split("created")[-1].split("guide:")[-1])


@pytest.mark.parametrize("line, words_", [
    ('SHAPE = "area"', "spec.py SHAPE: 'area' is not one of its MEASURES"),
    ('PLOTS = (("stopped", "robots stopped"), ("nope", "x"))', "PLOTS: 'nope' is not one of"),
    ('RESULT = ("delivered", "OK")', "RESULT: ('delivered', 'OK') is not (summary key"),
    ('LOAD = ("power",)', "LOAD: ('power',) is not (held, needed)"),
    ('SUMMARY = (("stopped", "{stopped"),)', "SUMMARY: '{stopped'"),
    ('HEADER = "{robots!x}"', "HEADER: '{robots!x}'"),
    ('MEASURES = (("stopped", "robots", "extra"),)', "MEASURES: ('stopped', 'robots', 'extra')"),
])
def test_a_wrong_words_declaration_is_one_line_naming_it(line, words_, tmp_path, capsys):
    name = "odd"        # one name in every case: each folder is its own module
    assert main(["behaviour", "new", name, "--into", str(tmp_path)]) == 0
    spec = tmp_path / name / "spec.py"
    spec.write_text(spec.read_text() + "\n" + line + "\n")
    capsys.readouterr()
    assert main(["run", "--behaviour", str(tmp_path / name), "--set", "maxTicks=5"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words_ in err and f"behaviour {name!r}" in err


def test_the_thesis_held_power_text_is_integer_math_printed_as_g():
    # firmware subset (no floats): hundredths printed the way "%g" prints weight units
    from firmware_logic.behaviours.thesis import _weight_text
    for centi in list(range(0, 1001)) + [12345, 65500]:
        assert _weight_text(centi) == f"{centi / 100:g}", centi


def test_the_live_view_data_of_a_scaffolded_behaviour_speaks_its_words(tiny):
    import json

    from bridge.view.sources import SimSource
    src = SimSource(scenario.load("default").replace(behaviour=str(tiny)), 1)
    try:
        src.control("step", {"ticks": 100})
        info, st = src.info(), src.state()
    finally:
        src.close()
    assert ["stopped", "robots resting in a heap"] in info["measures"]
    assert info["load"] is None and info["shape"] is False
    shown = {m["title"]: m["value"] for m in st["measures"]}
    assert shown["robots resting in a heap"] == len(st["touches"])
    assert "robots in the biggest heap" in shown
    no_thesis_words(json.dumps([info, st["measures"], st["status"], st["events"]]))
