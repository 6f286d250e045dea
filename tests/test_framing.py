"""COBS + CRC framing (firmware_logic/framing.py)."""

from __future__ import annotations

import random

from hypothesis import given, settings
from hypothesis import strategies as st

from firmware_logic import framing
from firmware_logic import messages as msg


def frame(kind: int, node: int, fields: tuple) -> bytes:
    enc = framing.Encoder()
    args = list(fields) + [0] * (6 - len(fields))
    n = enc.frame(kind, node, *args)
    return bytes(enc.out[:n])


def feed(dec: framing.Decoder, data: bytes) -> list[tuple[int, int, tuple]]:
    out = []
    for b in data:
        if dec.feed(b):
            out.append((dec.node, dec.kind, tuple(dec.fields[:dec.nfields])))
    return out


def field_values(kind: int, rnd: random.Random) -> tuple:
    vals = []
    for _, size, signed in msg.fields(kind):
        bits = size * 8
        lo, hi = (-(1 << (bits - 1)), (1 << (bits - 1)) - 1) if signed else (0, (1 << bits) - 1)
        vals.append(rnd.randint(lo, hi))
    return tuple(vals)


def test_crc16_check_value() -> None:
    # the catalogue check value of CRC-16/CCITT-FALSE
    assert framing.crc16(b"123456789", 9) == 0x29B1


def test_cobs_known_vectors() -> None:
    out = bytearray(300)
    cases = [(b"\x00", b"\x01\x01"), (b"\x00\x00", b"\x01\x01\x01"),
             (b"\x11\x22\x00\x33", b"\x03\x11\x22\x02\x33"), (b"\x11\x22\x33\x44", b"\x05\x11\x22\x33\x44"),
             (bytes(range(1, 255)), b"\xff" + bytes(range(1, 255)))]
    for raw, enc in cases:
        n = framing.cobs_encode(raw, len(raw), out)
        assert bytes(out[:n]) == enc
        back = bytearray(300)
        m = framing.cobs_decode(enc, len(enc), back)
        assert bytes(back[:m]) == raw


@given(st.binary(max_size=600))
def test_cobs_roundtrip(raw: bytes) -> None:
    out = bytearray(len(raw) + len(raw) // 254 + 2)
    n = framing.cobs_encode(raw, len(raw), out)
    assert 0 not in out[:n]
    back = bytearray(len(raw) + 1)
    m = framing.cobs_decode(out, n, back)
    assert bytes(back[:m]) == raw


def test_every_kind_roundtrips() -> None:
    rnd = random.Random(4)
    dec = framing.Decoder()
    for kind in msg.SCHEMA:
        for _ in range(50):
            node = rnd.randint(0, 127)
            f = field_values(kind, rnd)
            data = frame(kind, node, f)
            assert len(data) <= framing.MAX_FRAME
            assert data[0] == 0 and data[-1] == 0 and 0 not in data[1:-1]
            assert feed(dec, data) == [(node, kind, f)]
    assert dec.error_counts() == {}


def test_resync_after_garbage_and_truncation() -> None:
    dec = framing.Decoder()
    good = frame(msg.TOUCH, 3, (7, 1, 2, 3, 4, 100))
    stream = (b"\xde\xad\xbe\xef" + b"\x00" + good[:5] + b"\x00" + bytes(range(1, 60)) + b"\x00"
              + good + good)
    got = feed(dec, stream)
    assert got == [(3, msg.TOUCH, (7, 1, 2, 3, 4, 100))] * 2
    errs = dec.error_counts()
    assert sum(errs.values()) == 3
    assert errs.get("overflow") == 1


def test_junk_without_a_delimiter_never_costs_the_next_frame() -> None:
    # the sender's leading delimiter ends whatever was on the line before
    dec = framing.Decoder()
    good = frame(msg.ACK, 2, (9,))
    for junk in (b"\x05\x01", b"\xff" * 40, good[:-3], b"\x02\x03junk"):
        assert feed(dec, junk + good) == [(2, msg.ACK, (9,))]


def test_every_single_byte_corruption_is_detected() -> None:
    good = frame(msg.TOUCH, 9, (200, -5, 6, -7, 8, 65535))
    for i in range(len(good) - 1):
        for flip in (0x01, 0x80, 0xFF):
            bad = bytearray(good)
            bad[i] ^= flip
            dec = framing.Decoder()
            got = feed(dec, bytes(bad) + good)
            # the corrupted frame never comes out; the next one always does
            assert got[-1] == (9, msg.TOUCH, (200, -5, 6, -7, 8, 65535))
            assert len(got) == 1, (i, flip, got)


def test_wrong_length_and_unknown_kind_are_counted() -> None:
    enc = framing.Encoder()
    enc.raw[0] = msg.ACK
    enc.raw[1] = 1
    enc.raw[2] = 5
    enc.raw[3] = 6        # ACK has one data byte; two is a length fault
    n = enc.frame_raw(4)
    dec = framing.Decoder()
    assert feed(dec, bytes(enc.out[:n])) == []
    enc.raw[0] = 15
    n = enc.frame_raw(3)
    assert feed(dec, bytes(enc.out[:n])) == []
    assert dec.error_counts() == {"length": 1, "kind": 1}


@settings(max_examples=200)
@given(st.binary(max_size=200), st.integers(0, 127))
def test_random_bytes_never_crash_and_never_block_the_next_frame(junk: bytes, node: int) -> None:
    dec = framing.Decoder()
    feed(dec, junk)
    good = frame(msg.HELLO, node, (1, 100, 1))
    # one delimiter ends whatever the junk left open; then the frame gets through
    assert feed(dec, b"\x00" + good)[-1] == (node, msg.HELLO, (1, 100, 1))
