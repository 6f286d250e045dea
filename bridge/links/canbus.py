"""python-can backends of the link registry, with errors converted at the seam."""

from __future__ import annotations

import contextlib
from typing import Any, Iterator

import can

from bridge.links.errors import LinkInitError, LinkOperationError, LinkTimeoutError


@contextlib.contextmanager
def converted(what: str) -> Iterator[None]:
    """Turn python-can's errors into the link error tree, naming `what`."""
    try:
        yield
    except can.CanTimeoutError as err:
        raise LinkTimeoutError(f"{what}: timed out ({err})") from err
    except can.CanInitializationError as err:
        raise LinkInitError(f"{what}: {err}") from err
    except can.CanInterfaceNotImplementedError as err:
        raise LinkInitError(f"{what}: interface not available ({err})") from err
    except (can.CanOperationError, can.CanError) as err:
        raise LinkOperationError(f"{what}: {err}") from err
    except OSError as err:
        raise LinkInitError(f"{what}: {err}") from err


def _bus(what: str, **kw: Any) -> can.BusABC:
    with converted(f"cannot open {what}"):
        try:
            return can.Bus(**kw)
        except ValueError as err:
            raise LinkInitError(f"cannot open {what}: {err}") from err


def open_virtual(channel: str) -> can.BusABC:
    return _bus(f"virtual://{channel}", interface="virtual", channel=channel,
                receive_own_messages=False)


def open_socketcan(channel: str) -> can.BusABC:
    return _bus(f"socketcan://{channel}", interface="socketcan", channel=channel)


def open_slcan(channel: str, bitrate: int | None = None, baud: int = 115200,
               settle_ms: int | None = None) -> can.BusABC:
    """settle_ms: wait after opening the port (python-can's default, 2 s, lets an
    Arduino-style board reset; a pty or a CANable needs 0)."""
    kw: dict[str, Any] = {"tty_baudrate": baud}
    if settle_ms is not None:
        kw["sleep_after_open"] = settle_ms / 1000.0
    if bitrate is not None:
        kw["bitrate"] = bitrate
    return _bus(f"slcan://{channel}", interface="slcan", channel=channel, **kw)


def open_interface(channel: str, bitrate: int | None = None) -> can.BusABC:
    interface, _, chan = channel.partition("/")
    if interface == "udp_multicast":
        raise LinkInitError("can://udp_multicast/... is not allowed: it leaves the machine; "
                            "use virtual://CHANNEL")
    kw: dict[str, Any] = {}
    if bitrate is not None:
        kw["bitrate"] = bitrate
    return _bus(f"can://{channel}", interface=interface, channel=chan, **kw)
