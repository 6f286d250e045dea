"""Which files a recording can be: python-can formats by suffix, and the
sidecar beside each. Kept free of python-can so the CLI's help can list them
without importing it."""

from __future__ import annotations

from pathlib import Path

from bridge.errors import UsageError

SUFFIXES = (".blf", ".asc", ".log", ".csv", ".trc")
# python-can gzips its text formats only: its Logger refuses .blf.gz
GZ_SUFFIXES = tuple(s + ".gz" for s in SUFFIXES if s != ".blf")
FORMATS = SUFFIXES + GZ_SUFFIXES


def meta_path(path: Path) -> Path:
    """The sidecar FILE.json of recording FILE."""
    return Path(str(path) + ".json")


def record_format(path: Path, option: str = "--record") -> str:
    """The python-can format of a recording path ('.blf', '.log.gz', ...);
    UsageError naming the supported suffixes when python-can cannot write
    and read it back."""
    path = Path(path)
    name = path.name.lower()
    supported = ", ".join(FORMATS)
    fmt = next((f for f in sorted(FORMATS, key=len, reverse=True) if name.endswith(f)), None)
    if fmt is None:
        if name.endswith(".blf.gz"):
            raise UsageError(f"{option} {path}: python-can cannot gzip .blf (a binary, "
                             f"already compressed format); supported: {supported}")
        raise UsageError(f"{option} {path}: unknown recording format; expected a file "
                         f"ending in one of {supported}")
    # python-can reads the format of a .gz file from exactly its last two suffixes
    if fmt.endswith(".gz") and len(path.suffixes) != 2:
        raise UsageError(f"{option} {path}: python-can needs a .gz recording named "
                         f"NAME{fmt} with no other dot in NAME")
    return fmt
