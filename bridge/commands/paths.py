"""Output paths checked before a command starts its work.

A run or a sweep can take minutes; finding out afterwards that its output
cannot be written loses all of it. Each check here probes the real file
system (a temporary file in the target directory) and leaves nothing
behind, so a refused command creates no file and no directory.
"""

from __future__ import annotations

import os
from pathlib import Path

from bridge.errors import UsageError


def _why(err: OSError) -> str:
    return err.strerror or str(err)


def _probe_dir(path: Path, option: str) -> None:
    """Write and delete a temporary file in an existing directory."""
    # imported here: tempfile brings shutil and random, which a run without
    # output paths never needs
    import tempfile
    try:
        with tempfile.TemporaryFile(dir=path, prefix=".touchswarm-probe-"):
            pass
    except OSError as err:
        raise UsageError(f"{option} {path}: cannot write in this directory ({_why(err)}); "
                         "expected a writable directory") from None


def check_out_dir(path: Path, option: str = "--out") -> None:
    """Refuse an output directory that exists as a file or cannot be created or
    written. A missing directory is created for the probe and removed again."""
    path = Path(path)
    if path.exists():
        if not path.is_dir():
            raise UsageError(f"{option} {path}: is a file; expected a directory "
                             "(created if missing)")
        _probe_dir(path, option)
        return
    created: list[Path] = []
    missing = [path, *[p for p in path.parents if not p.exists()]]
    try:
        for d in reversed(missing):
            d.mkdir()
            created.append(d)
        _probe_dir(path, option)
    except OSError as err:
        blocker = next((p for p in path.parents if p.exists()), None)
        if blocker is not None and not blocker.is_dir():
            raise UsageError(f"{option} {path}: {blocker} is a file, so no directory can be "
                             "made under it; expected a directory path") from None
        raise UsageError(f"{option} {path}: cannot create this directory ({_why(err)}); "
                         "expected a writable directory") from None
    finally:
        for d in reversed(created):
            try:
                d.rmdir()
            except OSError:
                pass        # something else wrote there meanwhile: not ours to delete


def check_out_file(path: Path, option: str, example: str) -> None:
    """Refuse an output file whose directory is missing or not writable, or
    which is a directory. `example` is a file name to suggest."""
    path = Path(path)
    if path.is_dir():
        raise UsageError(f"{option} {path}: is a directory; expected a file path such as "
                         f"{path / example}")
    parent = path.parent
    if not parent.exists():
        raise UsageError(f"{option} {path}: directory {parent} does not exist; create it "
                         "first or choose a file in an existing directory")
    if not parent.is_dir():
        raise UsageError(f"{option} {path}: {parent} is a file, not a directory; expected "
                         "a file path in an existing directory")
    _probe_dir(parent, option)
    if path.exists() and not path.is_file():
        # /dev/full takes an open and fails every write, a FIFO blocks: only
        # after the work would the write fail
        raise UsageError(f"{option} {path}: not a regular file (a device, FIFO or "
                         f"socket); expected a file path such as {parent / example}")
    if path.exists() and not os.access(path, os.W_OK):
        raise UsageError(f"{option} {path}: the existing file is read-only; expected a "
                         "writable file")


def path_arg(text: str) -> Path:
    """An argparse type for a path: refuses the empty string, which Path()
    would quietly turn into the current directory."""
    import argparse
    if not text.strip():
        raise argparse.ArgumentTypeError("an empty path; expected a file or directory name")
    return Path(text)
