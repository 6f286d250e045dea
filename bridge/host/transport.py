"""RobotTransport (bridge/transport.py) over a python-can bus."""

from __future__ import annotations

import can

from bridge.links.canbus import converted
from bridge.links.codec import BadFrames, Decoder, Message, encode

BATCH = 4096
MALFORMED = "malformed adapter line"


class CanTransport:
    """Decoded robot messages from a bus; bad frames counted, never passed on."""

    def __init__(self, bus: can.BusABC, bad: BadFrames | None = None) -> None:
        self.bus = bus
        self.decoder = Decoder("host", bad or BadFrames("host"))
        self.frames_in = 0
        self.frames_out = 0
        self._closed = False

    def _recv(self, timeout: float) -> can.Message | None:
        try:
            with converted("host recv"):
                return self.bus.recv(timeout)
        except (ValueError, IndexError):      # an adapter line python-can cannot parse
            self.decoder.bad.add(MALFORMED)
            return None

    def poll(self, timeout: float) -> list[Message]:
        out: list[Message] = []
        frame = self._recv(max(timeout, 0.0))
        if frame is None:
            return out
        decode = self.decoder.decode
        recv = self.bus.recv
        append = out.append
        n = 0
        # the hot loop calls python-can directly; errors are converted below
        try:
            while frame is not None:
                n += 1
                m = decode(frame)
                if m is not None:
                    append(m)
                if n >= BATCH:
                    break
                frame = recv(0.0)
        except (ValueError, IndexError):
            self.decoder.bad.add(MALFORMED)
        except can.CanError:
            self.frames_in += n
            with converted("host recv"):
                raise
        self.frames_in += n
        return out

    def send(self, node: int, kind: int, fields: tuple) -> None:
        with converted("host send"):
            self.bus.send(encode(node, kind, fields))
        self.frames_out += 1

    def bad_frames(self) -> dict[str, int]:
        return dict(self.decoder.bad.counts)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self.bus.shutdown()

    def __enter__(self) -> "CanTransport":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
