"""Reading a small text file a user names (a scenario, an experiment, a
recording's sidecar): a regular file of at most MAX_BYTES, read as UTF-8.
A device (/dev/zero), a FIFO (which would block for ever) or a huge file is
refused in one line before anything is read into memory."""

from __future__ import annotations

import os
import stat
from pathlib import Path

from sim_backend.errors import SimError

MAX_BYTES = 1 << 20       # 1 MiB: a scenario with a drawn arena is a few kB


class TextFileError(SimError, ValueError):
    """Why a file cannot be read as a small text file (no path in the text:
    the caller names the file and its role)."""


def read_small_text(path: str | Path, limit: int = MAX_BYTES) -> str:
    """The file's text; TextFileError for a file that is not a regular file,
    is larger than `limit` bytes, cannot be read or is not UTF-8."""
    try:
        # O_NONBLOCK: opening a FIFO with no writer must not block; fstat then
        # says what was opened (no race with a file swapped after a stat)
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except OSError as err:
        raise TextFileError(err.strerror or str(err)) from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            kind = ("a FIFO" if stat.S_ISFIFO(st.st_mode) else
                    "a directory" if stat.S_ISDIR(st.st_mode) else "a device or special file")
            raise TextFileError(f"{kind}, not a regular file")
        if st.st_size > limit:
            raise TextFileError(f"{st.st_size:,} bytes, more than the {limit:,} allowed")
        data = os.read(fd, limit + 1)
        chunks = [data]
        while data and sum(map(len, chunks)) <= limit:
            data = os.read(fd, limit + 1)
            chunks.append(data)
        raw = b"".join(chunks)
        if len(raw) > limit:
            raise TextFileError(f"more than the {limit:,} bytes allowed")
    except OSError as err:
        raise TextFileError(err.strerror or str(err)) from None
    finally:
        os.close(fd)
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as err:
        raise TextFileError(f"not UTF-8 text (byte {err.start})") from None
