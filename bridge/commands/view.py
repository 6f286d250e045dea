"""`touchswarm view`: a live view of a mission in the browser (docs/view.md)."""

from __future__ import annotations

import argparse

from bridge.commands import numbers as N
from bridge.commands.paths import path_arg
from bridge.commands.run import add_scenario_args, scenario_from_args

DEFAULT_PORT = 8765
DEFAULT_SPEED = 20.0     # ticks per second: the default scenario is home in about 9 s


def register(sub) -> None:
    from bridge.view.sources import SPEED_MAX, SPEED_MIN
    p = sub.add_parser(
        "view",
        description="Serve a page on 127.0.0.1 that shows a mission as it happens: the arena "
                    "with the object, the field, robots coloured by state, touches numbered "
                    "in order, the behaviour's measures and reporters with their titles (and, "
                    "when it declares them, the perceived shape and its load, e.g. the "
                    "thesis's power against weight), bad frames and an event log. "
                    "Without --journal it runs the scenario in the reference engine with "
                    "play / pause / step / speed controls; with --journal it follows a "
                    "`touchswarm host` journal read-only (give the host's "
                    "--scenario/--set so the arena matches). Runs until Ctrl-C.",
        epilog="examples:\n"
               "  touchswarm view --scenario ant --seed 7          # then open the URL\n"
               "  touchswarm view --journal host.db --port 0\n"
               "  touchswarm view --screenshot live_view.png --at-tick 400",
        formatter_class=argparse.RawDescriptionHelpFormatter)
    add_scenario_args(p)
    p.add_argument("--journal", type=path_arg, metavar="PATH",
                   help="follow this `touchswarm host` journal (SQLite, opened read-only) "
                        "instead of simulating")
    p.add_argument("--port", type=N.count(0, 65535, what="a TCP port"), default=DEFAULT_PORT,
                   help="TCP port on 127.0.0.1 (0: any free port; default: %(default)s)")
    p.add_argument("--paused", action="store_true",
                   help="start the simulated run paused (default: playing)")
    p.add_argument("--speed", type=N.positive("ticks per second"), metavar="TICKS_PER_S",
                   help=f"simulated ticks per second while playing, {SPEED_MIN:g}..{SPEED_MAX:g} "
                        f"(default: {DEFAULT_SPEED:g})")
    p.add_argument("--screenshot", type=path_arg, metavar="FILE.png",
                   help="save a PNG of the page in headless chromium and exit (a simulated "
                        "run is first stepped to --at-tick)")
    p.add_argument("--at-tick", type=N.count(0, what="ticks"), metavar="N",
                   help="with --screenshot: the tick to show (default: the convergence, "
                        "or the end of the run)")
    p.set_defaults(func=cmd_view)


def cmd_view(args: argparse.Namespace) -> int:
    from bridge.errors import UsageError
    from bridge.view.server import ViewServer
    from bridge.view.sources import SPEED_MAX, SPEED_MIN, JournalSource, SimSource

    sc = scenario_from_args(args)
    if args.journal is not None:
        for given, option in ((args.paused, "--paused"), (args.speed is not None, "--speed")):
            if given:
                raise UsageError(f"{option}: only for a simulated run, not with --journal "
                                 "(the host sets the pace)")
    if args.speed is None:
        args.speed = DEFAULT_SPEED
    if not SPEED_MIN <= args.speed <= SPEED_MAX:
        raise UsageError(f"--speed {args.speed:g}: expected {SPEED_MIN:g}..{SPEED_MAX:g} "
                         "ticks per second")
    if args.at_tick is not None and args.screenshot is None:
        raise UsageError(f"--at-tick {args.at_tick}: only with --screenshot FILE")
    if args.screenshot is not None:
        from bridge.commands.paths import check_out_file
        check_out_file(args.screenshot, "--screenshot", "live_view.png")
        if args.screenshot.suffix.lower() != ".png":
            raise UsageError(f"--screenshot {args.screenshot}: expected a .png file")
    source: JournalSource | SimSource
    if args.journal is not None:
        source = JournalSource(args.journal, sc)
    else:
        source = SimSource(sc, args.seed, playing=not args.paused and args.screenshot is None,
                           speed=args.speed)
    try:
        server = ViewServer(source, args.port)
    except BaseException:
        source.close()
        raise
    if args.screenshot is not None:
        return _screenshot(args, server, source)
    print(f"live view on {server.url} (Ctrl-C stops)", flush=True)
    try:
        server.serve_forever()
    finally:
        server.server_close()
        source.close()
    return 0


def _screenshot(args: argparse.Namespace, server, source) -> int:
    from bridge.view.browser import screenshot
    server.start()
    try:
        if source.kind == "sim":
            engine = source.engine
            with source.lock:
                while not engine.finished() and (
                        engine.tick < args.at_tick if args.at_tick is not None
                        else getattr(engine.coordinator, "converged_tick", -1) < 0):
                    engine.step()
        tick = source.state()["tick"]
        screenshot(server.url, args.screenshot, tick)
    finally:
        server.stop()
    ended = " (the run ended there)" if args.at_tick is not None and tick < args.at_tick else ""
    print(f"live view at tick {tick}{ended} saved to {args.screenshot}")
    return 0
