"""Robot bodies by URL: which body gives a node of a mission its senses and moves it.

    sim://                                       the simulated body (the default)
    khepera:///dev/ttyUSB0?baud=38400            a Khepera II on RS-232; firmware on the host
    gogo:///dev/ttyUSB1                          a GoGo Board robot; firmware on the host
    mpy:///dev/ttyACM0                           a deployed MicroPython robot (its firmware
                                                 on the board, its senses from the sim world)

Under a scheme the port is a device path or any pyserial URL:
`khepera://loop://`, `gogo://socket://host:7777`, `khepera:///dev/pts/5`.
Options common to the robots on a bench say where the robot was put down
(`x`, `y` in patches, `heading` in degrees clockwise from north) and how big
a patch is on the floor (`patch_mm`); each kind adds its own (see OPTIONS).

REGISTRY maps a scheme to "module:function", imported only when a URL of
that scheme is opened (pyserial is not needed for sim://). A new body kind
is one module with an `open_body(spec, ctx)` function plus one entry in
REGISTRY, EXPECTED and OPTIONS.

Every URL problem (unknown scheme, no port, unknown or bad option, a device
that does not exist, a device that does not answer at open) is one
BodyURLError, a UsageError: the CLI prints its one line and exits 2 before
the mission starts.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Any, Callable, Protocol, TypedDict
from urllib.parse import parse_qsl

from bridge import devices
from bridge.errors import UsageError

__all__ = ["REGISTRY", "EXPECTED", "OPTIONS", "BodyURLError", "BodySpec", "BodyContext",
           "OpenedBody", "Opened", "open_host_body", "start_pose", "parse_body_url", "parse_assignment", "open_body"]

REGISTRY: dict[str, str] = {
    "sim": "bridge.bodies.sim:open_body",
    "khepera": "bridge.bodies.khepera:open_body",
    "gogo": "bridge.bodies.gogo:open_body",
    "mpy": "bridge.bodies.mpy:open_body",
}

EXPECTED: dict[str, str] = {
    "sim": "sim://",
    "khepera": "khepera:///dev/ttyUSB0?baud=38400",
    "gogo": "gogo:///dev/ttyUSB1",
    "mpy": "mpy:///dev/ttyACM0",
}

# where the robot was put down, and the floor size of one patch
POSE = {"x": float, "y": float, "heading": float, "patch_mm": float}

# option name -> converter; a converter raises ValueError on a bad value
OPTIONS: dict[str, dict[str, Callable[[str], Any]]] = {
    "sim": {},
    "khepera": {"baud": int, **POSE, "cruise": int, "touch_threshold": int, "dark": int,
                "light_step": int},
    "gogo": {"baud": int, **POSE, "mm_s_per_level": float, "wheel_base_mm": float,
             "power": int, "dark": int, "light_step": int, "touch_threshold": int},
    "mpy": {"baud": int, "x": float, "y": float},   # where its simulated body starts
}

BAUDS = {"khepera": (9600, 19200, 38400, 57600, 115200)}


class BodyURLError(UsageError):
    """A body URL is malformed, names an unknown kind or option, or a device
    that does not exist or does not answer; the message names what and
    shows the expected form."""


@dataclass(frozen=True)
class BodySpec:
    """A parsed body URL."""

    url: str
    scheme: str
    port: str                       # device path or pyserial URL ("" for sim://)
    options: dict[str, Any] = field(default_factory=dict)

    def get(self, key: str, default: Any = None) -> Any:
        return self.options.get(key, default)


@dataclass
class BodyContext:
    """What a mission tells a body it opens: the node, where the scenario put
    that robot (used when the URL gives no x / y), the arena, the tick, the
    clock, and the link the host-side firmware talks over."""

    node: int
    x_patch: float
    y_patch: float
    arena: int                      # the world's half size in patches
    tick_s: float
    clock: Any = None               # bridge.serial.hostbody.Clock; None: wall clock
    link: Any = None                # robot_send / robot_recv (sim_backend.link.Link)


class OpenedBody(Protocol):
    """What a factory returns; a context manager (close() never raises).

    kind "sim": the node stays simulated. kind "host": `hal` is a HostBody
    the mission steps the node's firmware on. kind "tether": `transport` is
    the host's end of a link (sim_backend.link.HostEnd) to a board running its own firmware, whose senses and
    actions the mission serves from the sim world."""

    kind: str
    spec: BodySpec
    hal: Any
    transport: Any

    def describe(self) -> str: ...

    def close(self) -> None: ...

    def __enter__(self) -> "OpenedBody": ...

    def __exit__(self, *exc: object) -> None: ...


class Opened:
    """The OpenedBody the factories return: what to step or serve, and the
    resources to close (last opened first)."""

    def __init__(self, kind: str, spec: BodySpec, hal: Any = None, transport: Any = None,
                 closers: list[Callable[[], None]] | None = None, text: str = "") -> None:
        self.kind = kind
        self.spec = spec
        self.hal = hal
        self.transport = transport
        self._closers = list(closers or [])
        self._text = text or spec.url

    def describe(self) -> str:
        return self._text

    def close(self) -> None:
        # drivers' close() never raise (their contract); keep going regardless
        while self._closers:
            self._closers.pop()()

    def __enter__(self) -> "Opened":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


class Pose(TypedDict):
    """A host-side body's constructor keywords for where it starts."""
    x_mm: float
    y_mm: float
    heading: float
    patch_mm: float


def start_pose(spec: BodySpec, ctx: BodyContext) -> Pose:
    """x_mm, y_mm, heading and patch_mm for a host-side body: where the URL
    says the robot was put down, else the scenario's start of that node."""
    patch_mm = float(spec.get("patch_mm", 50.0))
    x = float(spec.get("x", ctx.x_patch))
    y = float(spec.get("y", ctx.y_patch))
    if abs(x) > ctx.arena + 0.5 or abs(y) > ctx.arena + 0.5:
        raise BodyURLError(f"body {spec.url!r}: start ({x:g}, {y:g}) is outside the arena "
                           f"(-{ctx.arena}..{ctx.arena} patches)")
    return {"x_mm": x * patch_mm, "y_mm": y * patch_mm,
            "heading": float(spec.get("heading", 0.0)) % 360, "patch_mm": patch_mm}


def open_host_body(spec: BodySpec, device: Callable[[], Any],
                   body: Callable[[Any], Any], stop: Callable[[Any, Any], None],
                   text: str) -> Opened:
    """Open a device and the HostBody on it (kind "host"). Either failing
    (a port that cannot be opened, a robot that does not answer the
    body's set-up) is a BodyURLError naming the URL, raised before any
    mission tick; the device is closed again. `stop(device, body)` runs
    when the mission ends, before the port closes."""
    from bridge.serial.errors import SerialLinkError
    try:
        dev = device()
    except SerialLinkError as err:
        raise BodyURLError(f"body {spec.url!r}: {err}") from err
    try:
        hal = body(dev)
    except SerialLinkError as err:
        dev.close()
        raise BodyURLError(f"body {spec.url!r}: {err}") from err
    except BaseException:
        dev.close()
        raise

    def quiet_stop() -> None:
        # a device already gone at the end is not worth an error at exit
        try:
            stop(dev, hal)
        except SerialLinkError:
            pass
    return Opened("host", spec, hal=hal, closers=[dev.close, quiet_stop], text=text)


def _split(url: str) -> tuple[str, str, str]:
    """(scheme, port, query). Not urlsplit: the port may itself be a URL
    with its own `//` (`khepera://loop://`); our options are the part after
    the last `?`, so a pyserial URL with options of its own cannot take ours."""
    scheme, sep, rest = url.partition("://")
    if not sep:
        raise BodyURLError(f"body {url!r}: expected SCHEME://PORT, one of "
                           + ", ".join(EXPECTED.values()))
    port, q, query = rest.rpartition("?")
    if not q:
        port, query = rest, ""
    return scheme, port, query


def parse_body_url(url: str) -> BodySpec:
    """Parse and check a body URL (nothing is opened)."""
    scheme, port, query = _split(url.strip())
    if scheme not in REGISTRY:
        raise BodyURLError(f"body {url!r}: unknown kind {scheme!r}; expected one of "
                           + ", ".join(EXPECTED.values()))
    expected = EXPECTED[scheme]
    if scheme == "sim":
        if port or query:
            raise BodyURLError(f"body {url!r}: sim:// takes no port or options; "
                               f"expected {expected}")
        return BodySpec(url, scheme, "")
    if not port:
        raise BodyURLError(f"body {url!r}: missing port; expected {expected} "
                           f"(a device path or a pyserial URL such as loop://)")
    allowed = OPTIONS[scheme]
    opts: dict[str, Any] = {}
    for key, value in parse_qsl(query, keep_blank_values=True):
        if key not in allowed:
            raise BodyURLError(f"body {url!r}: unknown option {key!r} (options: "
                               f"{', '.join(allowed) or 'none'}); expected {expected}")
        if key in opts:
            raise BodyURLError(f"body {url!r}: option {key!r} given twice")
        try:
            opts[key] = allowed[key](value)
        except ValueError:
            raise BodyURLError(f"body {url!r}: option {key}={value!r} is not "
                               f"{'an integer' if allowed[key] is int else 'a number'}; "
                               f"expected {expected}") from None
    if "baud" in opts and opts["baud"] <= 0:
        raise BodyURLError(f"body {url!r}: baud={opts['baud']} must be positive")
    if scheme in BAUDS and "baud" in opts and opts["baud"] not in BAUDS[scheme]:
        raise BodyURLError(f"body {url!r}: baud={opts['baud']}: a {scheme} runs at one of "
                           + ", ".join(map(str, BAUDS[scheme])))
    if opts.get("patch_mm", 1.0) <= 0:
        raise BodyURLError(f"body {url!r}: patch_mm={opts['patch_mm']} must be positive")
    # a device path that is not there fails here, with its name, rather than
    # as pyserial's errno text after the other bodies were opened
    why = devices.missing(port)
    if why:
        raise BodyURLError(f"body {url!r}: {why}")
    return BodySpec(url, scheme, port, opts)


def parse_assignment(text: str) -> tuple[int, BodySpec]:
    """`NODE=URL` (the --body argument) as (node, spec)."""
    node_s, eq, url = text.partition("=")
    if not eq or not url:
        raise BodyURLError(f"--body {text!r}: expected NODE=URL, e.g. "
                           f"--body 3={EXPECTED['khepera']}")
    try:
        node = int(node_s)
    except ValueError:
        raise BodyURLError(f"--body {text!r}: node {node_s!r} is not a number") from None
    return node, parse_body_url(url)


def open_body(spec: BodySpec, ctx: BodyContext) -> OpenedBody:
    """Open the body a spec names, through its registry entry."""
    modname, _, func = REGISTRY[spec.scheme].partition(":")
    try:
        mod = importlib.import_module(modname)
    except ImportError as err:
        raise BodyURLError(f"body {spec.url!r}: {spec.scheme}:// needs {err.name!r}, which "
                           f"is not installed ({err})") from err
    return getattr(mod, func)(spec, ctx)
