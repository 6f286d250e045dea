"""`touchswarm run`: the whole mission in the simulated world."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Any, Callable

from bridge.commands.paths import path_arg
from bridge.errors import UsageError


def add_scenario_args(p: argparse.ArgumentParser) -> None:
    from sim_backend.scenario import SEED_MAX, SEED_MIN
    p.add_argument("--scenario", default="default", metavar="NAME|FILE",
                   help="built-in scenario name (see `touchswarm scenarios`) or a TOML file "
                        "(default: %(default)s)")
    p.add_argument("--seed", type=int, default=1,
                   help=f"run seed, {SEED_MIN}..{SEED_MAX:,}; the same seed gives the same "
                        "run (default: %(default)s)")
    p.add_argument("--robots", type=int, metavar="N",
                   help="number of robots; overrides the scenario's agents")
    p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override any scenario key, e.g. --set sigRadius=8 (repeatable, "
                        "one per key; `touchswarm scenarios` lists keys and ranges)")
    p.add_argument("--behaviour", metavar="NAME|FOLDER",
                   help="the behaviour to run, by name (`touchswarm behaviours`) or folder; "
                        "the same as --set behaviour=NAME (default: the scenario's, thesis)")
    add_trust_arg(p)


def add_trust_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument("--trust-behaviour", action="append", default=[], metavar="DIR",
                   help="a behaviour folder a data file (scenario TOML, recording sidecar, "
                        "journal) may name; its code runs (repeatable; docs/security.md)")


def trust_from_args(args: argparse.Namespace) -> None:
    """The folders the command line names are trusted; a data file may name
    no other (sim_backend/registry.py named_by_data)."""
    from sim_backend import registry
    for ref in getattr(args, "trust_behaviour", None) or ():
        if not Path(ref).is_dir():
            raise UsageError(f"--trust-behaviour {ref}: not a folder")
        registry.trust(ref)
    if getattr(args, "behaviour", None) is not None:
        registry.trust(args.behaviour)


def parse_value(text: str):
    from sim_backend.scenario import flat_toml
    flat = flat_toml(f"v = {text}")
    if flat is not None:
        return flat["v"]
    import tomllib
    try:
        return tomllib.loads(f"v = {text}")["v"]
    except tomllib.TOMLDecodeError:
        return text


def check_link_limits(sc, link: str) -> None:
    """A real link carries node ids in 7 bits and patch coordinates in one
    signed byte; the simulator alone can go further (vectorised sweeps)."""
    from firmware_logic.messages import MAX_NODE
    if sc.agents > MAX_NODE:
        raise UsageError(f"agents: {sc.agents} robots do not fit the {link} link's node ids; "
                         f"allowed 1..{MAX_NODE} (more only with --link inproc)")
    if sc.worldSize > 120:
        raise UsageError(f"worldSize: {sc.worldSize} exceeds the {link} link's one-byte patch "
                         f"coordinates; allowed 10..120 (more only with --link inproc)")


def parse_overrides(items: list[str]) -> dict:
    """--set KEY=VALUE items as scenario changes (values read as TOML)."""
    changes: dict[str, Any] = {}
    for item in items:
        key, eq, value = item.partition("=")
        key = key.strip()
        if not eq or not key or not value.strip():
            raise UsageError(f"--set {item!r}: expected KEY=VALUE, e.g. --set sigRadius=6")
        if key in changes:
            # the last one would silently win: say which value was meant
            raise UsageError(f"--set {key} given twice ({changes[key]!r} and "
                             f"{parse_value(value.strip())!r}); give each key once")
        changes[key] = parse_value(value.strip())
    return changes


def scenario_from_args(args: argparse.Namespace):
    """The scenario and seed the command line asks for, both validated."""
    from sim_backend import scenario
    scenario.check_seed(args.seed, "--seed")
    changes = parse_overrides(args.set)
    trust_from_args(args)
    if "behaviour" in changes:
        from sim_backend import registry
        registry.trust(str(changes["behaviour"]))
    sc = scenario.load(args.scenario)
    if args.robots is not None:
        if "agents" in changes and changes["agents"] != args.robots:
            raise UsageError(f"--robots {args.robots} and --set agents={changes['agents']} "
                             "disagree; give one of them")
        changes["agents"] = args.robots
    if getattr(args, "behaviour", None) is not None:
        if "behaviour" in changes and changes["behaviour"] != args.behaviour:
            raise UsageError(f"--behaviour {args.behaviour} and --set behaviour="
                             f"{changes['behaviour']} disagree; give one of them")
        changes["behaviour"] = args.behaviour
    return sc.replace(**changes) if changes else sc


class RunHelp(argparse.RawDescriptionHelpFormatter):
    """--animate's help names sim_backend.animate's MAX_FRAMES, read when
    the help is printed: a run without --animate never imports that module
    (5-6 M instructions of start-up)."""

    def _expand_help(self, action: argparse.Action) -> str:
        text = super()._expand_help(action)
        if "{MAX_FRAMES}" not in text:
            return text
        from sim_backend.animate import MAX_FRAMES
        return text.replace("{MAX_FRAMES}", str(MAX_FRAMES))


def register(sub) -> None:
    from bridge.commands.numbers import count
    from bridge.record.formats import FORMATS
    p = sub.add_parser(
        "run",
        description="Run one scenario to the end with no hardware: the behaviour's robots "
                    "and its host coordinator (the thesis's search, touch, converge and "
                    "carry the object home). Prints a summary in the behaviour's words: "
                    "its measures and reporters (docs/outputs.md). Exit status 0 when the "
                    "mission ended (the coordinator's delivered_tick; the thesis: the "
                    "object delivered home), 1 when it did not, 2 on bad input (checked "
                    "before the run starts, output paths included).",
        epilog="examples:\n"
               "  touchswarm run                                  # the default scenario\n"
               "  touchswarm run --scenario ant --seed 7 --out ant7/\n"
               "  touchswarm run --robots 12 --set sigRadius=8 --json\n"
               "  touchswarm run --link can --record run.blf      # then: touchswarm replay "
               "run.blf",
        formatter_class=RunHelp)
    add_scenario_args(p)
    p.add_argument("--out", type=path_arg, metavar="DIR",
                   help="directory (created if missing) for world.png, summary.json and the "
                        "thesis-style CSV records")
    p.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    p.add_argument("--link", choices=["inproc", "can"], default="inproc",
                   help="how robots reach the host coordinator: in-process lists, or CAN "
                        "frames over a python-can virtual channel (default: %(default)s)")
    p.add_argument("--record", type=path_arg, metavar="FILE",
                   help="record all traffic, SENSOR and ACTION capture frames included, as a "
                        "python-can log plus FILE.json (scenario, seed, frame count, summary); "
                        "the suffix picks the format: " + ", ".join(FORMATS))
    p.add_argument("--trace", type=path_arg, metavar="FILE",
                   help="one row per tick: robots per state, power, IoU, touches, messages, "
                        "bad frames, the behaviour's reporters and the new shape estimate's "
                        "IoU and recognition posterior (docs/outputs.md); the "
                        "suffix picks the format: .csv or .parquet")
    p.add_argument("--animate", type=path_arg, metavar="FILE",
                   help="draw the run over time to FILE.gif (or .mp4 when ffmpeg is on PATH): "
                        "trails coloured by state, the field, touches in order, the "
                        "behaviour's reporters in the title (the thesis: also the perceived "
                        "shape and the path home). Frames: the start, every --frame-every ticks "
                        "and the last tick; by default the stride doubles until at most "
                        "{MAX_FRAMES} frames are kept (the default scenario: 87 frames, "
                        "about 1.3 MB)")
    p.add_argument("--frame-every", type=count(1, what="ticks per frame"), metavar="K",
                   help="with --animate: one frame every K ticks (default: automatic, see "
                        "--animate)")
    p.set_defaults(func=cmd_run, quiet_logging=True)


def check_outputs(args: argparse.Namespace) -> None:
    """Refuse unusable --out and --record paths before the run, not after it.
    --out is created first, so --trace/--record/--animate may name files in
    it; it is removed again (when still empty) if another path is refused."""
    from bridge.commands.paths import check_out_dir
    if args.out is None:
        _check_files(args)
        return
    check_out_dir(args.out, "--out")
    created = [d for d in (args.out, *args.out.parents) if not d.exists()]
    args.out.mkdir(parents=True, exist_ok=True)
    try:
        _check_files(args)
    except UsageError:
        for d in created:
            try:
                d.rmdir()
            except OSError:
                break           # not empty: something else wrote there meanwhile
        raise


def _check_files(args: argparse.Namespace) -> None:
    from bridge.commands.paths import check_out_file
    from bridge.record.formats import meta_path, record_format
    if args.record is not None:
        record_format(args.record)
        check_out_file(args.record, "--record", "run.blf")
        check_out_file(meta_path(args.record), "--record (its sidecar)", "run.blf.json")
    if args.trace is not None:
        from sim_backend.trace import trace_format
        _check_media(args.trace, "--trace", "trace.csv", trace_format)
    if args.animate is not None:
        from sim_backend.animate import animation_format
        _check_media(args.animate, "--animate", "run.gif", animation_format)
    elif args.frame_every is not None:
        raise UsageError(f"--frame-every {args.frame_every}: only with --animate FILE")


def _check_media(path: Path, option: str, example: str, fmt: Callable[[Path], str]) -> None:
    """A writable file path whose suffix names a format we can write here."""
    from bridge.commands.paths import check_out_file
    from sim_backend.observe import OutputFormatError
    check_out_file(path, option, example)
    try:
        fmt(path)
    except OutputFormatError as err:
        raise UsageError(f"{option} {err}") from None


def cmd_run(args: argparse.Namespace) -> int:
    from sim_backend.engine import Engine

    if args.link != "inproc" or args.record or args.out or args.trace or args.animate:
        # the CAN link, the recorder and matplotlib log; the plain run's
        # modules do not (perception.detail), so it leaves logging unloaded
        from bridge.cli import configure_logging
        configure_logging(args.verbose)
    sc = scenario_from_args(args)
    if args.link == "can":
        check_link_limits(sc, "CAN")
    else:
        from sim_backend.scenario import link_faults
        if link_faults(sc):
            raise UsageError(f"{link_faults(sc)[0]}: a link fault needs a link; add --link can")
    check_outputs(args)
    nodes = list(range(1, sc.agents + 1))
    link = None
    if args.link == "can":
        from bridge.links.canlink import CanLink, faults_of
        up, down = faults_of(sc, args.seed)
        link = CanLink(nodes, faults_up=up, faults_down=down)
    recorder = None
    try:
        if args.record:
            from bridge.record.recorder import Recorder, recording_engine
            from sim_backend.engine import InprocLink
            recorder = Recorder(args.record, sc, args.seed, link=args.link)
            engine = recording_engine(sc, args.seed, link or InprocLink(nodes), recorder)
        else:
            engine = Engine(sc, args.seed, link=link)
        return _run(args, sc, engine, recorder)
    finally:
        if recorder is not None:
            recorder.close()
        if link is not None:
            link.close()


def _watchers(args: argparse.Namespace, engine) -> tuple:
    """The per-tick observers the options ask for: (trails, trace, animation)."""
    trails = trace = anim = None
    from perception.tracker import attach
    attach(engine)          # the new shape estimate and recognition: summary fields, trace columns
    if args.out or args.animate:
        from sim_backend.observe import Trails
        trails = Trails(engine)
    if args.trace:
        from sim_backend.trace import Trace
        trace = Trace(engine)
    if args.animate:
        from sim_backend.animate import Animation
        assert trails is not None       # args.animate made them above
        anim = Animation(engine, trails, every=args.frame_every)
    return trails, trace, anim


def _run(args: argparse.Namespace, sc, engine, recorder) -> int:
    trails, trace, anim = _watchers(args, engine)
    bar = None
    if sys.stderr.isatty() and not args.json:
        from tqdm import tqdm
        bar = tqdm(total=sc.maxTicks, unit="tick", leave=False)
    result = engine.run(progress=(lambda tick: bar.update(1)) if bar is not None else None)
    if bar is not None:
        bar.close()
    summary = result.summary()
    if recorder is not None:
        recorder.close(summary)
    if args.out:
        from sim_backend.records import write_records
        from sim_backend.render import render
        write_records(result, args.out)
        render(result, args.out / "world.png", trails)
    if trace is not None:
        trace.write(args.trace)
    if anim is not None:
        frames = anim.write(args.animate, progress=_frames_bar(args))
    if args.json:
        import json         # only here: its import compiles its patterns (5 M instructions)
        print(json.dumps(summary, sort_keys=True))
    else:
        print(format_summary(summary, engine.behaviour, result.coordinator))
        if args.out:
            print(f"records and world.png written to {args.out}/")
        if args.record:
            print(f"traffic recorded to {args.record} ({recorder.frames} frames)")
        if trace is not None:
            print(f"per-tick trace written to {args.trace} ({len(trace.rows)} rows)")
        if anim is not None:
            print(f"animation written to {args.animate} ({frames} frames, one every "
                  f"{anim.every} ticks)")
    return 0 if summary["delivered"] else 1


def _frames_bar(args: argparse.Namespace):
    """progress(done, total) for --animate: a bar of frames drawn on a
    terminal (drawing takes longer than the run), nothing otherwise."""
    if not sys.stderr.isatty() or args.json:
        return None
    from tqdm import tqdm
    bar = None

    def progress(done: int, total: int) -> None:
        nonlocal bar
        if bar is None:
            bar = tqdm(total=total, unit="frame", desc=f"drawing {args.animate}", leave=False)
        bar.update(1)
        if done == total:
            bar.close()
    return progress


def _perception_lines(s: dict) -> list[str]:
    """The new estimate and recognition (perception), when measured."""
    if "estimate_iou" not in s:
        return []
    by = " (the decision's verdict)" if s.get("verdict_by") == "decision" else ""
    if s.get("recognised") is None:
        # the end-state fields (a mission or a sweep row) carry no threshold
        above = (f" above p {s['recognition_threshold']:g}" if "recognition_threshold" in s
                 else "")
        rec = f"no shape{above} (best p {s['p']:.3f}){by}"
    else:
        when = f", from tick {s['recognised_tick']}" if "recognised_tick" in s else ""
        rec = f"{s['recognised']} p {s['p']:.3f}{when}{by}"
    how = (f" ({s['estimate_kind']}; hull minus free {s['hull_free_iou']:.3f})"
           if "estimate_kind" in s else "")
    return [f"  estimate IoU     {s['estimate_iou']:.3f}{how}",
            f"  recognised       {rec}"]


def _decision_lines(s: dict) -> list[str]:
    """What the host decided by recognition (a behaviour's recognition measures)."""
    if "releases" not in s:
        return []
    when = ("never" if s["target_tick"] is None else
            f"tick {s['target_tick']}, p {s['target_permille'] / 1000:.3f}")
    wrong = "WRONG transport (a decoy)" if s.get("wrong_transport") else "no wrong transport"
    return [f"  target           recognised {when}; {s['releases']} decoy releases; {wrong}"]


def format_summary(s: dict, behaviour=None, coordinator=None) -> str:
    """The text summary in the behaviour's own words (sim_backend/words.py):
    its header and measure lines, the new estimate and recognition when
    measured, the result line."""
    from sim_backend import registry
    from sim_backend import words
    b = registry.load(behaviour) if behaviour is None or isinstance(behaviour, str) \
        else behaviour
    return "\n".join([*words.summary_lines(b, s, coordinator), *_perception_lines(s),
                      *_decision_lines(s), words.result_line(b, s)])
