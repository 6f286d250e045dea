"""Serial framing of messages: COBS with a CRC-16, one zero byte between frames.

Runs on the robot (MicroPython) and on the host, so it is written in the
firmware subset (docs/subset.md) and allocates nothing per byte or frame.

A frame, before stuffing:

    kind (1 byte) | node (1 byte) | payload (messages.pack, 0..8 bytes) | crc16 (2 bytes, big endian)

on the wire: 0x00 | COBS(that) | 0x00   (at most 16 bytes)

The CRC is CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) over kind, node
and payload. The frame is COBS-encoded (no zero byte inside) and followed by
a 0x00 delimiter; the sender also puts a 0x00 before each frame, so junk
left on the line before it (noise, a truncated frame) ends there and never
costs the next frame. A receiver that starts mid-stream, or that sees a
corrupted byte, loses at most the frame in progress: it drops everything up
to the next 0x00 and starts again (resynchronisation).

Bad frames are counted by fault in `Decoder.errors`, indexed by the ERR_*
codes below (ERR_NAMES gives their names).

Outside a run of frames the line is not ours: a board's REPL talks on the
same wire before its firmware's first frame (mpremote's raw REPL, whose
raw-paste header even holds a 0x00) and after its last one (the raw REPL's
end of output, its answers to whatever arrives next). `Decoder.hunt()`
says so: until the next valid frame, bytes are skipped (`skipped`), never
counted as bad frames; the host calls it whenever it joins a line (port
opened or reopened) and when a board says its run has ended.
"""

from firmware_logic import messages as msg

MAX_PAYLOAD = 8
MAX_RAW = 2 + MAX_PAYLOAD + 2            # kind, node, payload, crc
MAX_ENCODED = MAX_RAW + 1                # COBS adds one byte per 254 (a frame < 254)
MAX_FRAME = MAX_ENCODED + 2              # with the leading and trailing delimiters
MIN_RAW = 4

ERR_CRC = 0        # checksum mismatch
ERR_COBS = 1       # a COBS code points past the end of the frame
ERR_SHORT = 2      # fewer bytes than kind + node + crc
ERR_LONG = 3       # more bytes than the largest frame before a delimiter
ERR_KIND = 4       # unknown message kind
ERR_LENGTH = 5     # payload length does not match the kind's DLC
ERR_NAMES = ("crc", "cobs", "short", "overflow", "kind", "length")

SUBSET_SETUP = ("Decoder.error_counts",)


def crc16(data, n):
    """CRC-16/CCITT-FALSE of data[0:n]."""
    crc = 0xFFFF
    i = 0
    while i < n:
        crc ^= data[i] << 8
        b = 0
        while b < 8:
            if crc & 0x8000:
                crc = ((crc << 1) ^ 0x1021) & 0xFFFF
            else:
                crc = (crc << 1) & 0xFFFF
            b += 1
        i += 1
    return crc


def cobs_encode(src, n, out):
    """COBS-encode src[0:n] into out; return the encoded length (no delimiter)."""
    code_pos = 0
    code = 1
    o = 1
    i = 0
    while i < n:
        b = src[i]
        if b == 0:
            out[code_pos] = code
            code_pos = o
            o += 1
            code = 1
        else:
            out[o] = b
            o += 1
            code += 1
            if code == 0xFF and i + 1 < n:
                out[code_pos] = code
                code_pos = o
                o += 1
                code = 1
        i += 1
    out[code_pos] = code
    return o


def cobs_decode(src, n, out):
    """Decode COBS src[0:n] into out; return the length, or -1 if malformed."""
    i = 0
    o = 0
    while i < n:
        code = src[i]
        if code == 0 or i + code > n + 1:
            return -1
        i += 1
        j = 1
        while j < code:
            if i >= n:
                return -1
            out[o] = src[i]
            o += 1
            i += 1
            j += 1
        if code < 0xFF and i < n:
            out[o] = 0
            o += 1
    return o


class Encoder:
    """Builds frames into one preallocated buffer."""

    def __init__(self):
        self.raw = bytearray(MAX_RAW)
        self.out = bytearray(MAX_FRAME)
        self.stuffed = bytearray(MAX_ENCODED)
        self.args = [0, 0, 0, 0, 0, 0]

    def frame(self, kind, node, a0, a1, a2, a3, a4, a5):
        """Frame one message; return the byte count written to `self.out`
        (delimiter included). Raises messages.SchemaError on a bad field."""
        a = self.args
        a[0] = a0
        a[1] = a1
        a[2] = a2
        a[3] = a3
        a[4] = a4
        a[5] = a5
        raw = self.raw
        raw[0] = kind
        raw[1] = node
        # pack writes from offset 0: stage in self.out, then copy to raw[2:]
        n = msg.pack(kind, a, self.out)
        i = 0
        while i < n:
            raw[2 + i] = self.out[i]
            i += 1
        return self.frame_raw(n + 2)

    def frame_raw(self, n):
        """Frame self.raw[0:n] (kind, node, payload) as it is; return the length."""
        raw = self.raw
        c = crc16(raw, n)
        raw[n] = c >> 8
        raw[n + 1] = c & 0xFF
        out = self.out
        m = cobs_encode(raw, n + 2, self.stuffed)
        out[0] = 0
        i = 0
        while i < m:
            out[1 + i] = self.stuffed[i]
            i += 1
        out[m + 1] = 0
        return m + 2


class Decoder:
    """Feed bytes one at a time; `feed` returns 1 when a valid frame is ready.

    After a 1, `kind`, `node`, `count` (payload length) and `payload`
    (bytearray, first `count` bytes valid) describe the frame, and
    `fields` holds the unpacked fields (`nfields` of them).
    """

    def __init__(self):
        self.buf = bytearray(MAX_ENCODED)
        self.raw = bytearray(MAX_ENCODED)
        self.payload = bytearray(MAX_PAYLOAD)
        self.fields = [0, 0, 0, 0, 0, 0]
        self.nfields = 0
        self.n = 0
        self.dropping = 0
        self.kind = 0
        self.node = 0
        self.count = 0
        self.frames = 0
        self.errors = [0, 0, 0, 0, 0, 0]
        self.hunting = 0
        self.skipped = 0

    def reset(self):
        """Forget any partial frame (e.g. after the port was reopened)."""
        self.n = 0
        self.dropping = 0

    def hunt(self):
        """Forget any partial frame; until the next valid frame, what arrives
        is not a frame gone bad but someone else's bytes: skipped, counted in
        `skipped`, never in `errors` (see the module's docstring)."""
        self.reset()
        self.hunting = 1

    def _bad(self, code):
        if not self.hunting:
            self.errors[code] += 1
        return 0

    def feed(self, b):
        if self.hunting and b != 0:
            self.skipped += 1
        if b == 0:
            n = self.n
            self.n = 0
            if self.dropping:
                self.dropping = 0
                return 0
            if n == 0:
                return 0          # idle delimiters are fine
            return self._finish(n)
        if self.dropping:
            return 0
        if self.n >= MAX_ENCODED:
            self.dropping = 1
            self.n = 0
            return self._bad(ERR_LONG)
        self.buf[self.n] = b
        self.n += 1
        return 0

    def _finish(self, n):
        raw = self.raw
        m = cobs_decode(self.buf, n, raw)
        if m < 0:
            return self._bad(ERR_COBS)
        if m < MIN_RAW:
            return self._bad(ERR_SHORT)
        if m > MAX_RAW:
            return self._bad(ERR_LONG)
        c = crc16(raw, m - 2)
        if raw[m - 2] != (c >> 8) or raw[m - 1] != (c & 0xFF):
            return self._bad(ERR_CRC)
        kind = raw[0]
        if kind not in msg.SCHEMA:
            return self._bad(ERR_KIND)
        count = m - 4
        if count != msg.dlc(kind):
            return self._bad(ERR_LENGTH)
        p = self.payload
        i = 0
        while i < count:
            p[i] = raw[2 + i]
            i += 1
        self.kind = kind
        self.node = raw[1]
        self.count = count
        self.nfields = self._unpack(kind, count)
        self.frames += 1
        if self.hunting:
            self.hunting = 0
            self.skipped -= n          # this frame's own bytes were no junk
        return 1

    def _unpack(self, kind, count):
        # messages.unpack needs len(data) == dlc; decode here without slicing
        out = self.fields
        p = self.payload
        pos = 0
        i = 0
        for f in msg.fields(kind):
            size = f[1]
            v = 0
            j = 0
            while j < size:
                v |= p[pos + j] << (8 * j)
                j += 1
            if f[2] and v >= 1 << (size * 8 - 1):
                v -= 1 << (size * 8)
            out[i] = v
            pos += size
            i += 1
        return i

    def error_counts(self):
        """{fault name: count} of the faults seen so far (host side)."""
        d = {}
        i = 0
        while i < len(ERR_NAMES):
            if self.errors[i]:
                d[ERR_NAMES[i]] = self.errors[i]
            i += 1
        return d
