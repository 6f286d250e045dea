"""The host's end of a link (sim_backend/link.py HostEnd) over a python-can bus."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING, Callable

import can

from bridge.links.canbus import converted, shutdown_quietly
from bridge.links.codec import OUT_OF_RANGE, BadFrames, Decoder, Message, encode
from bridge.links.errors import LinkError
from firmware_logic import messages as msg
from sim_backend import registry

if TYPE_CHECKING:
    from bridge.links.secoc import Sealer

BATCH = 4096       # at most this many frames per poll, so a flood cannot starve the tick
CHECK_EVERY = 64   # frames read between two looks at the clock
MALFORMED = "malformed adapter line"
KEYED_HELLO = "authenticated HELLO to a host without keys"
_HELLO_IDS = range(msg.HELLO << 7, (msg.HELLO + 1) << 7)


class CanTransport:
    """Decoded robot messages from a bus; bad frames counted, never passed on."""

    def __init__(self, bus: can.BusABC, bad: BadFrames | None = None,
                 clock: Callable[[], float] = time.monotonic,
                 sealer: "Sealer | None" = None) -> None:
        self.bus = bus
        self.sealer = sealer        # authenticated host commands (bridge/links/secoc.py)
        self.clock = clock          # what poll's deadline is measured on
        self.decoder = Decoder("host", bad or BadFrames("host"))
        self._locked: set[int] = set()
        if sealer is not None:
            sealer.bad = self.decoder.bad
            self._locked = sealer.locked      # the same set: filled as nodes are locked out
        self.keyed_hellos: dict[int, int] = {}    # a host without keys: sealed HELLOs per node
        self.frames_in = 0
        self.frames_out = 0
        self._closed = False

    def poll(self, timeout: float) -> list[Message]:
        """Messages received within `timeout` seconds: waits up to `timeout` for
        the first frame, then takes the frames waiting, and returns by the
        deadline (looked at every CHECK_EVERY frames: at most that many past
        it, a fraction of a millisecond; a read under way is finished, never
        cut), or after BATCH frames. So poll(0) takes up to CHECK_EVERY of
        the frames waiting, not one."""
        if self._closed:
            raise LinkError("host recv: the transport is closed")
        clock = self.clock
        deadline = clock() + max(timeout, 0.0)
        out: list[Message] = []
        decode = self.decoder.decode if self.sealer is None else self._decode_keyed
        recv = self.bus.recv
        append = out.append
        n = 0
        try:
            with converted("host recv"):
                frame = recv(max(timeout, 0.0))
                while frame is not None:
                    n += 1
                    m = decode(frame)
                    if m is not None:
                        append(m)
                    elif self.sealer is None and frame.arbitration_id in _HELLO_IDS:
                        self._plain_host_hello(frame)
                    if n >= BATCH or (not n % CHECK_EVERY and clock() >= deadline):
                        break
                    frame = recv(0.0)
        except (ValueError, IndexError):      # an adapter line python-can cannot parse
            self.decoder.bad.add(MALFORMED)
        finally:
            self.frames_in += n
        return out

    def _decode_keyed(self, frame: can.Message) -> Message | None:
        """With keys: a HELLO is verified first (secoc.Sealer.open_hello),
        every other report opened (secoc.Sealer.open_report) and then checked
        like a plain one; frames of a locked-out node are dropped."""
        ident = frame.arbitration_id
        if ident in _HELLO_IDS or self._locked:
            return self._keyed_slow(frame)
        decoder = self.decoder
        if decoder.bound is not registry._ACTIVE and decoder.fixed is None:
            decoder._bind()
        if (ident >> 7) in decoder.accept and ident & 0x7F and not (
                frame.is_extended_id or frame.is_remote_frame or frame.is_error_frame
                or frame.is_fd):
            # a sealed report (the body of _opened, inlined: every keyed report)
            f = self.sealer.open_report(frame, ident & 0x7F)    # type: ignore[union-attr]
            if f is None:
                return None
            entry = decoder.fast.get(ident)
            if entry is not None and entry[4](f):
                return entry[0], entry[1], f
            decoder.bad.add(OUT_OF_RANGE, frame)
            return None
        return decoder.decode(frame)

    def _opened(self, frame: can.Message, ident: int) -> Message | None:
        """A sealed report, verified and restored to its plain fields, then
        held to the same ranges as a plain one."""
        assert self.sealer is not None
        f = self.sealer.open_report(frame, ident & 0x7F)
        if f is None:
            return None
        entry = self.decoder.fast.get(ident)
        if entry is not None and entry[4](f):
            return entry[0], entry[1], f
        self.decoder.bad.add(OUT_OF_RANGE, frame)
        return None

    def _keyed_slow(self, frame: can.Message) -> Message | None:
        sealer = self.sealer
        assert sealer is not None
        ident = frame.arbitration_id
        if (ident & 0x7F) in sealer.locked:
            from bridge.links.secoc import LOCKED_NODE
            self.decoder.bad.add(LOCKED_NODE, frame)
            return None
        if frame.is_extended_id or frame.is_remote_frame or frame.is_error_frame:
            return self.decoder.decode(frame)
        if ident in _HELLO_IDS:
            opened = sealer.open_hello(frame, ident & 0x7F)
            if opened is None:
                return None
            return self.decoder.decode(opened)
        if (ident >> 7) in self.decoder.accept and ident & 0x7F:
            return self._opened(frame, ident)
        return self.decoder.decode(frame)

    def _plain_host_hello(self, frame: can.Message) -> None:
        """A host without keys that hears sealed HELLOs (8 bytes) twice from
        one node: the robots have a key file and will drop its commands."""
        from bridge.links.secoc import MAC_BYTES, MISMATCH_AFTER
        if frame.is_extended_id or len(frame.data) != msg.dlc(msg.HELLO) + 1 + MAC_BYTES:
            return
        node = frame.arbitration_id & 0x7F
        self.decoder.bad.add(KEYED_HELLO, frame)
        k = self.keyed_hellos[node] = self.keyed_hellos.get(node, 0) + 1
        if k >= MISMATCH_AFTER:
            raise LinkError(f"robot {node} sends authenticated HELLOs: it has a key file; "
                            "give `touchswarm host` the same --keys FILE as the robots")

    def send(self, node: int, kind: int, fields: tuple) -> None:
        if self._closed:
            raise LinkError("host send: the transport is closed")
        frame = encode(node, kind, fields)
        frames = [frame] if self.sealer is None else self.sealer.seal(frame)
        with converted("host send"):
            for f in frames:
                self.bus.send(f)
        self.frames_out += len(frames)

    def bad_frames(self) -> dict[str, int]:
        return dict(self.decoder.bad.counts)

    def close(self) -> None:
        """Idempotent; never raises (a lost link fails to close as well)."""
        if not self._closed:
            self._closed = True
            shutdown_quietly(self.bus, "host")

    def __enter__(self) -> "CanTransport":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
