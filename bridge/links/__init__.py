"""Links by URL. A CAN link is a python-can bus chosen by URL scheme:

    virtual://CHANNEL                          python-can's in-process bus (CI)
    socketcan://can0                           Linux SocketCAN
    slcan:///dev/ttyACM0?bitrate=500000        SLCAN adapter (CANable style) or a pty
    can://INTERFACE/CHANNEL?bitrate=500000     any python-can interface

Backends are resolved lazily from REGISTRY (scheme -> "module:function"), so a
backend's dependency is imported only when it is used.
"""

from __future__ import annotations

import importlib
from typing import Any
from urllib.parse import parse_qsl, urlsplit

from bridge.links.errors import LinkError, LinkTimeoutError, LinkURLError

__all__ = ["REGISTRY", "open_bus", "parse_url", "refuse_in_process", "LinkError",
           "LinkTimeoutError", "LinkURLError"]

REGISTRY: dict[str, str] = {
    "virtual": "bridge.links.canbus:open_virtual",
    "socketcan": "bridge.links.canbus:open_socketcan",
    "slcan": "bridge.links.canbus:open_slcan",
    "can": "bridge.links.canbus:open_interface",
    "slcan-pty": "bridge.links.slcan_pty:open_pty_bus",
}

EXPECTED = {
    "virtual": "virtual://CHANNEL",
    "socketcan": "socketcan://can0",
    "slcan": "slcan:///dev/ttyACM0?bitrate=500000[&baud=115200][&settle_ms=2000]",
    "can": "can://INTERFACE/CHANNEL?bitrate=500000",
    "slcan-pty": "slcan-pty:///path/of/link?bitrate=500000 (serves an SLCAN face on a pty)",
}

OPTIONS = {
    "virtual": (),
    "socketcan": (),
    "slcan": ("bitrate", "baud", "settle_ms"),
    "can": ("bitrate",),
    "slcan-pty": ("bitrate",),
}


def parse_url(url: str) -> tuple[str, str, dict[str, int]]:
    """(scheme, channel, options) of a link URL; rejects unknown options."""
    parts = urlsplit(url)
    scheme = parts.scheme
    if scheme not in REGISTRY:
        known = ", ".join(EXPECTED[s] for s in REGISTRY)
        raise LinkURLError(f"unknown link {url!r}: expected one of {known}")
    if scheme == "can":
        channel = parts.netloc + ("/" + parts.path.lstrip("/") if parts.path.strip("/") else "")
    elif scheme in ("slcan", "slcan-pty"):
        channel = parts.netloc + parts.path
    else:
        channel = parts.netloc + parts.path.rstrip("/")
    if not channel or (scheme == "can" and "/" not in channel):
        raise LinkURLError(f"{url!r}: missing channel; expected {EXPECTED[scheme]}")
    opts: dict[str, int] = {}
    for key, value in parse_qsl(parts.query, keep_blank_values=True):
        if key not in OPTIONS[scheme]:
            allowed = ", ".join(OPTIONS[scheme]) or "none"
            raise LinkURLError(f"{url!r}: unknown option {key!r} (options: {allowed}); "
                               f"expected {EXPECTED[scheme]}")
        try:
            opts[key] = int(value)
        except ValueError:
            raise LinkURLError(f"{url!r}: option {key}={value!r} is not an integer; "
                               f"expected {EXPECTED[scheme]}") from None
    return scheme, channel, opts


def refuse_in_process(url: str, command: str) -> None:
    """Refuse a link that cannot reach another process, for the commands that
    exist to run host and robots as separate processes. python-can's virtual
    bus lives inside one process: a host and a robots process on the same
    virtual:// channel would each wait for ever on a bus of their own."""
    if urlsplit(url).scheme == "virtual":
        raise LinkURLError(
            f"{command} --bus {url}: python-can's virtual bus does not cross processes, so "
            f"the other side would never be heard; use the SLCAN face on a pty (robots "
            f"--bus slcan-pty:///tmp/adapter, host --bus 'slcan:///tmp/adapter?settle_ms=0'; "
            f"docs/protocol.md) or one process: touchswarm run --link can")


def check_device(url: str, command: str) -> None:
    """Refuse an slcan:// link whose device path is not there (before any
    port opens, so nothing was done: a usage error)."""
    from bridge import devices
    scheme, channel, _ = parse_url(url)
    if scheme == "slcan":
        why = devices.missing(channel)
        if why:
            raise LinkURLError(f"{command} --bus {url}: {why}")


def open_bus(url: str) -> Any:
    """Open the python-can bus a URL names (a context manager; shutdown is idempotent)."""
    scheme, channel, opts = parse_url(url)
    modname, _, func = REGISTRY[scheme].partition(":")
    try:
        mod = importlib.import_module(modname)
    except ImportError as err:
        raise LinkError(f"link {scheme}:// needs {err.name!r}, which is not "
                        f"installed ({err})") from err
    return getattr(mod, func)(channel, **opts)
