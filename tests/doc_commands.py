"""Every command in README and the guide is run by a test.

The suite records each command line it runs, in process or as a subprocess
(bridge/cli.py writes one JSON line per `touchswarm` call to
TOUCHSWARM_ARGV_LOG, which conftest.py sets). When the whole suite has run,
conftest.py checks that every documented command was run with exit status 0
(or 1: it ran, and its outcome was a failure) in the same *form*: the same command and sub-command words, every option the
doc gives, and, where the doc names a value (a scenario, a preset, a
behaviour, the key of a --set or --grid), that value. Values the doc gives as
paths, numbers or device URLs match any value (a test runs `host --bus
socketcan://can0` over an SLCAN pty, `deploy --port /dev/ttyACM0` on a
MicroPython behind a pty). A test may add only the options in TEST_SIZE,
which make a run smaller or quieter, never different in kind.
"""

from __future__ import annotations

import argparse
import json
import re
import shlex
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOCS = ("README.md", "docs/writing-a-behaviour.md")
# options a test may add to a documented command: they shrink a run (fewer
# seeds, ticks, robots, a lighter object), pace it, run it in this process,
# or write one more output; none changes which rules run
TEST_SIZE = {"--seeds", "--json", "--out", "--engine", "--tick-ms", "--linger-ms", "--jobs",
             "--ticks", "--max-ticks", "--quiet", "--seed", "--robots", "--bus-timeout",
             "--node-timeout", "--no-plots", "--executor", "--chunk", "--overwrite",
             "--journal", "--retries", "--timeout", "--verbose", "-v",
             ("--set", "maxTicks"), ("--set", "agents"), ("--set", "objectWeight"),
             ("--scenario", "default"), ("--config", "NODE"), ("--config", "SEED"),
             ("--config", "MAX_TICKS"), ("--config", "LINGER"),
             # the live view rendered once in headless Chromium: a test has no eyes
             "--screenshot", "--at-tick", "--port"}
# options whose named value is part of the form (other values match anything)
NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_-]*$")
KEYED = {"--set", "--grid", "--config"}


@dataclass(frozen=True)
class Form:
    words: tuple[str, ...]                              # command and sub-command words
    options: frozenset[tuple[str, str | None]]          # (option, key or name or None)

    def covered_by(self, run: "Form") -> bool:
        if run.words != self.words:
            return False
        for opt, val in self.options:
            if not any(o == opt and (val is None or v == val) for o, v in run.options):
                return False
        for opt, val in run.options - self.options:
            if any(o == opt and (val is None or v == val) for o, v in self.options):
                continue                     # the doc's path or number, another value
            if opt not in TEST_SIZE and (opt, val) not in TEST_SIZE:
                return False
        return True

    def __str__(self) -> str:
        opts = " ".join(sorted(o if v is None else f"{o} {v}" for o, v in self.options))
        return " ".join(self.words) + (" " + opts if opts else "")


def documented(root: Path = ROOT) -> list[tuple[str, str]]:
    """(file, command line) of every `touchswarm` line in the docs' sh blocks."""
    out = []
    for name in DOCS:
        text = (root / name).read_text()
        for block in re.findall(r"```sh\n(.*?)```", text, re.S):
            for line in block.splitlines():
                line = line.split(" #")[0].strip()
                tokens = shlex.split(line, comments=True) if line else []
                while tokens and re.match(r"^[A-Z_]+=", tokens[0]):
                    tokens.pop(0)                 # VAR=value before the command
                if tokens and tokens[0] in ("touchswarm", ".venv/bin/touchswarm"):
                    out.append((name, " ".join(tokens[1:]).split(" && ")[0]))
    return out


def _parsers() -> argparse.ArgumentParser:
    from bridge.cli import build_parser
    return build_parser(full=True)


def _sub(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for a in parser._actions:
        if isinstance(a, argparse._SubParsersAction):
            return {k: v for k, v in a.choices.items() if v is not None}
    return {}


def form(argv: list[str], parser: argparse.ArgumentParser | None = None) -> Form:
    """The form of one command line (argv without the program name)."""
    parser = parser or _parsers()
    words: list[str] = []
    opts: set[tuple[str, str | None]] = set()
    i = 0
    while i < len(argv):
        tok = argv[i]
        subs = _sub(parser)
        if not tok.startswith("-"):
            if tok in subs:
                words.append(tok)
                parser = subs[tok]
            i += 1                           # a positional value: any value matches
            continue
        name, _, inline = tok.partition("=")
        action = parser._option_string_actions.get(name)
        takes = action is not None and action.nargs != 0
        value = inline if inline else (argv[i + 1] if takes and i + 1 < len(argv) else None)
        i += 1 + (1 if takes and not inline else 0)
        if name in KEYED and value is not None:
            opts.add((name, value.split("=")[0]))
        elif takes and value is not None and NAME.match(value) and not value.isdigit():
            opts.add((name, value))
        else:
            opts.add((name, None))
    return Form(tuple(words), frozenset(opts))


def ran(log: Path) -> list[Form]:
    """The forms of every command line the suite ran with exit status 0."""
    parser = _parsers()
    out = []
    if not log.exists():
        return out
    for line in log.read_text().splitlines():
        try:
            rec = json.loads(line)
        except ValueError:
            continue
        # 1: the command ran and its outcome is a failure (e.g. a host whose
        # robots are scripted and never deliver); the line itself held
        if rec.get("rc") in (0, 1):
            out.append(form(rec["argv"], parser))
    return out


def uncovered(log: Path, root: Path = ROOT) -> list[str]:
    """The documented commands no successful run in `log` covers."""
    parser = _parsers()
    runs = set(ran(log))
    missing = []
    for name, line in documented(root):
        f = form(shlex.split(line), parser)
        if not any(f.covered_by(r) for r in runs):
            missing.append(f"{name}: touchswarm {line}")
    return missing
