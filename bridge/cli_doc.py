"""docs/cli.md, generated from the argparse parsers (bridge/cli.py and each
command's register()): `python -m bridge.cli_doc > docs/cli.md`.

The reference is every parser's own --help text, so it cannot say anything
the command does not; tests/test_cli_doc.py checks that the committed file
equals this output. The help is formatted at a fixed width, whatever the
terminal.
"""

from __future__ import annotations

import argparse
import os
import sys
from typing import Iterator

WIDTH = "100"

HEAD = """# Command line reference

Generated from the command line's own parsers by
`python -m bridge.cli_doc > docs/cli.md` (a test checks that this file is
that output; edit the parsers, not this file). `touchswarm COMMAND --help`
prints the same text.

## Exit status

{status}
"""


def _parsers(p: argparse.ArgumentParser) -> Iterator[argparse.ArgumentParser]:
    """`p` and every sub-parser under it, depth first, in registration order."""
    yield p
    for action in p._actions:
        if isinstance(action, argparse._SubParsersAction):
            seen: set[int] = set()
            for sub in action.choices.values():
                if id(sub) not in seen:        # aliases name one parser twice
                    seen.add(id(sub))
                    yield from _parsers(sub)


def _status() -> str:
    """The exit-status paragraph of bridge/cli.py's docstring (written once there)."""
    from bridge import cli
    doc = cli.__doc__ or ""
    start = doc.index("Exit status")
    para = doc[start:].split("\n\n")[0]
    return " ".join(para.replace("Exit status (docs/cli.md):", "Exit status:").split())


def text() -> str:
    from bridge.cli_parser import build_parser
    old = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = WIDTH
    try:
        parser = build_parser(full=True)
        parts = [HEAD.format(status=_status())]
        for p in _parsers(parser):
            parts.append(f"## {p.prog}\n\n```text\n{p.format_help().rstrip()}\n```\n")
    finally:
        if old is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = old
    return "\n".join(parts)


def main() -> int:
    sys.stdout.write(text())
    return 0


if __name__ == "__main__":
    sys.exit(main())
