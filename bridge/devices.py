"""Device paths: one rule for every place a port is named (links, bodies,
host serial ports). A path that is not there is refused before anything
opens, with its name, rather than as pyserial's errno text after other
ports were opened. pyserial URLs (socket://, loop://, ...) are left to
pyserial."""

from __future__ import annotations

import os


def missing(port: str) -> str | None:
    """Why `port` cannot be a device (one line), or None if it may be."""
    if "://" in port or os.path.exists(port):
        return None
    return (f"no such device {port!r} (is it plugged in? `ls /dev/tty*` lists the "
            f"serial ports)")
