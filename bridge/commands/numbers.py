"""Typed numbers for command-line options, checked while parsing.

A period, a timeout or a count is refused by argparse itself, before any
port opens or any run starts, with one line naming the option and the range
(argparse prefixes "argument --OPTION:"). NaN and infinities are refused
everywhere: `nan <= 0` is False, so a plain comparison lets them through.
"""

from __future__ import annotations

import argparse
import math
from typing import Callable


def _float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"{text!r}: expected a finite number")
    return v


def _int(text: str) -> int:
    try:
        return int(text, 10)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None


def positive(unit: str) -> Callable[[str], float]:
    """A finite number > 0 (a period)."""
    def parse(text: str) -> float:
        v = _float(text)
        if v <= 0:
            raise argparse.ArgumentTypeError(f"{text}: expected {unit} > 0")
        return v
    return parse


def at_least(low: float, unit: str, note: str = "") -> Callable[[str], float]:
    """A finite number >= low (a timeout where 0 means never, a linger)."""
    def parse(text: str) -> float:
        v = _float(text)
        if v < low:
            raise argparse.ArgumentTypeError(f"{text}: expected {unit} >= {low:g}{note}")
        return v
    return parse


def share(text: str) -> float:
    """A probability of a fault: 0 <= p < 1."""
    v = _float(text)
    if not 0 <= v < 1:
        raise argparse.ArgumentTypeError(f"{text}: expected a share 0 <= p < 1")
    return v


def count(low: int, high: int | None = None, what: str = "") -> Callable[[str], int]:
    """A whole number in low..high (high None: no upper bound)."""
    def parse(text: str) -> int:
        v = _int(text)
        if v < low or (high is not None and v > high):
            span = f"{low}..{high}" if high is not None else f">= {low}"
            raise argparse.ArgumentTypeError(f"{text}: expected {what or 'a whole number'} "
                                             f"{span}")
        return v
    return parse
