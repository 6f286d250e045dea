"""Start-up of the command line: `touchswarm --version`, `--help` and
`run --json` (the default scenario), wall and CPU seconds per call, beside
the floors `python -c pass` and `python -c "import numpy"`, plus what
`python -X importtime` counts (modules imported, seconds in imports).

Each figure is the median of --reps fresh interpreters (wall clock, and
CPU from the child's rusage, as /usr/bin/time reports them), the commands
interleaved so a busy machine slows them alike, after one untimed call of
each. Every child reads and writes bytecode as a user's install does
(user_env), even where PYTHONDONTWRITEBYTECODE is set. `--tree DIR` (repeatable) times another source
tree too, e.g. an export of an older commit
(`git archive COMMIT | tar -x -C /tmp/old`), run as `python -c "from
bridge.cli import main; ..."` from that folder with this interpreter.
Prints one JSON object. Nothing here is asserted: tests/test_cli_imports.py
checks *what* is imported, never how long it takes.

`--instructions` adds what no load moves: instructions (valgrind's
cachegrind, `OPENBLAS_NUM_THREADS=1` and `PYTHONHASHSEED=0` so they repeat)
of each command and of `touchswarm run --json` against its floor, `python
-c "import numpy"` plus the run itself (a process running it twice less one
running it once: the second run, everything imported and warm).
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CLI = "import sys; from bridge.cli import main; sys.exit(main(sys.argv[1:]))"
COMMANDS = {"--version": ["--version"], "--help": ["--help"], "run --json": ["run", "--json"]}
FLOORS = {"python -c pass": "pass", "python -c 'import numpy'": "import numpy"}


def user_env(pycache: Path) -> dict[str, str]:
    """The environment of a user's process: bytecode read and written (a
    wheel's install compiles it; an editable one writes it on the first
    run). With PYTHONDONTWRITEBYTECODE set (as in this project's sessions)
    every call compiled the project's sources again, 0.1-0.2 s, while
    numpy's wheel brings its bytecode: a command paid what its floor did not.
    The bytecode goes under `pycache` (PYTHONPYCACHEPREFIX): no source
    tree is written to."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPYCACHEPREFIX"] = str(pycache)
    return env


ENV: dict[str, str] = dict(os.environ)       # every child's (main sets user_env)


def timed(argv: list[str], cwd: Path) -> tuple[float, float]:
    """(wall, user + system CPU) seconds of one child process."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    subprocess.run(argv, cwd=cwd, env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def import_time(args: list[str], cwd: Path) -> dict:
    """Modules imported and the seconds spent importing them (the top-level
    cumulative figures of -X importtime)."""
    err = subprocess.run([sys.executable, "-X", "importtime", "-c", CLI, *args], cwd=cwd,
                         env=ENV, capture_output=True, text=True).stderr
    rows = [line.split("|") for line in err.splitlines()
            if line.startswith("import time:") and not line.endswith("package")]
    top = [int(r[1]) for r in rows if not r[2].startswith("  ")]
    return {"modules": len(rows), "import_s": round(sum(top) / 1e6, 3)}


RUN_ONCE = ("import contextlib, io\nfrom bridge.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n    main(['run', '--json'])\n")


def instructions(argv: list[str], cwd: Path) -> int:
    """Instructions a child process executes, by cachegrind."""
    env = {**ENV, "OPENBLAS_NUM_THREADS": "1", "PYTHONHASHSEED": "0"}
    err = subprocess.run(["valgrind", "--tool=cachegrind", "--cache-sim=no",
                          "--cachegrind-out-file=/dev/null", *argv], cwd=cwd, env=env,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True).stderr
    refs = [line for line in err.splitlines() if "I   refs:" in line or "I refs:" in line]
    if not refs:
        raise SystemExit(f"bench/cli_startup.py: no instruction count from valgrind: "
                         f"{err.strip().splitlines()[-1:]}")
    return int(refs[-1].split(":")[1].replace(",", ""))


def count_instructions(trees: dict[str, Path]) -> dict:
    """Instructions (M) of every command and floor, and run --json over its floor."""
    py = sys.executable
    numpy = instructions([py, "-c", "import numpy"], Path("/"))
    out: dict = {"python -c pass": instructions([py, "-c", "pass"], Path("/")),
                 "python -c 'import numpy'": numpy}
    for label, tree in trees.items():
        for name, args in COMMANDS.items():
            out[f"{label}: touchswarm {name}"] = instructions([py, "-c", CLI, *args], tree)
        inside = (instructions([py, "-c", RUN_ONCE * 2], tree)
                  - instructions([py, "-c", RUN_ONCE], tree))
        run = out[f"{label}: touchswarm run --json"]
        out[f"{label}: run in process"] = inside
        out[f"{label}: run --json over its floor"] = round(run / (numpy + inside), 4)
    return {k: v if isinstance(v, float) else round(v / 1e6, 1) for k, v in out.items()}


def median(rows: list[tuple[float, float]]) -> dict:
    return {"wall_s": round(statistics.median(r[0] for r in rows), 3),
            "cpu_s": round(statistics.median(r[1] for r in rows), 3)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--reps", type=int, default=5, help="calls per figure (default: 5)")
    ap.add_argument("--tree", action="append", default=[], type=Path,
                    help="another source tree to time beside this one")
    ap.add_argument("--instructions", action="store_true",
                    help="also count instructions with valgrind's cachegrind (M)")
    a = ap.parse_args(argv)
    trees = {"this": ROOT, **{str(t): t.resolve() for t in a.tree}}
    with tempfile.TemporaryDirectory() as pycache:
        ENV.clear()
        ENV.update(user_env(Path(pycache)))
        out = measure(trees, a.reps)
        if a.instructions:
            out["instructions_M"] = count_instructions(trees)
    print(json.dumps(out, indent=1))
    return 0


def measure(trees: dict[str, Path], reps: int) -> dict:
    times: dict[str, list] = {}
    for k in range(reps + 1):           # the first round writes the bytecode, untimed
        for name, args in COMMANDS.items():
            for label, tree in trees.items():
                t = timed([sys.executable, "-c", CLI, *args], tree)
                if k:
                    times.setdefault(f"{label}: touchswarm {name}", []).append(t)
        for name, code in FLOORS.items():
            t = timed([sys.executable, "-c", code], Path("/"))
            if k:
                times.setdefault(name, []).append(t)
    return {"reps": reps, "cpus": os.cpu_count(), "load": os.getloadavg()[0],
            "seconds": {k: median(v) for k, v in times.items()},
            "imports": {f"{label}: touchswarm {name}": import_time(args, tree)
                        for name, args in COMMANDS.items() for label, tree in trees.items()}}


if __name__ == "__main__":
    sys.exit(main())
