"""The installed package's version (pyproject.toml's, the one place),
read from its installed metadata.

importlib.metadata finds it as well, but its import (email, zipfile,
csv, pathlib's globbing: ~30 ms, a third of `touchswarm --version`) is
most of what the command costs. The `.dist-info` (or `.egg-info`) folder
it would find first is read here with os and open alone; anything else
(an egg, a zip) goes to importlib.metadata.
"""

from __future__ import annotations

import os
import sys

NAME = "touchswarm"


def _normal(name: str) -> str:
    """A distribution name as importlib.metadata compares them (runs of
    - _ . as one _)."""
    out: list[str] = []
    for ch in name.lower():
        if ch not in "-_.":
            out.append(ch)
        elif not out or out[-1] != "\0":
            out.append("\0")           # a separator's mark, so a run of them is one
    return "".join(out).replace("\0", "_")


def _from_info_folder() -> str | None:
    """The Version header of the first `.dist-info` or `.egg-info` folder
    of this package on sys.path, in importlib.metadata's order and read as
    it reads one (METADATA, else PKG-INFO); None when that first match is
    of another form (an egg, a file): importlib.metadata decides then."""
    for entry in sys.path:
        if entry.lower().endswith(".egg"):
            return None
        try:
            children = os.listdir(entry or ".")
        except OSError:
            continue                # not a folder: a zip, or gone
        for child in children:
            low = child.lower()
            if low.endswith((".dist-info", ".egg-info")) and \
                    _normal(low.rpartition(".")[0].partition("-")[0]) == NAME:
                return _header(os.path.join(entry or ".", child))
    return None


def _header(folder: str) -> str | None:
    for name in ("METADATA", "PKG-INFO"):
        try:
            with open(os.path.join(folder, name), encoding="utf-8") as f:
                for line in f:
                    if line in ("\n", "\r\n"):
                        break       # the headers end; the description follows
                    if line.startswith("Version:"):
                        return line[len("Version:"):].strip()
            return None
        except (FileNotFoundError, NotADirectoryError):
            continue
        except OSError:
            return None
    return None


def version() -> str:
    """The installed version; "0+unknown" for a source tree never installed."""
    found = _from_info_folder()
    if found is not None:
        return found
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as dist_version
    try:
        return dist_version(NAME)
    except PackageNotFoundError:       # a source tree that was never installed
        return "0+unknown"
