"""argparse ``type=`` functions shared by every command line (agent, simhw, mstc up, ...).

Each turns a bad value into ``argparse.ArgumentTypeError``, which argparse reports as one
usage line (exit 2) instead of a traceback. No Zenoh here: options are checked before the bus
is loaded.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None


def positive(text: str) -> float:
    """A finite number > 0."""
    value = _number(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a number > 0, got {text!r}")
    return value


def seconds(text: str) -> float:
    """A finite number of seconds > 0."""
    value = _number(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a number of seconds > 0, got {text!r}")
    return value


def non_negative(text: str) -> float:
    """A finite number >= 0."""
    value = _number(text)
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"expected a finite number >= 0, got {text!r}")
    return value


def time_scale(text: str) -> float:
    """Simulated seconds per wall second: >= 0, where 0 and inf both mean as fast as possible."""
    value = _number(text)
    if math.isnan(value) or value < 0:
        raise argparse.ArgumentTypeError(
            f"time scale must be >= 0 (0 or inf = as fast as possible), got {text!r}")
    return value


def at_least(least: int) -> Callable[[str], int]:
    """A whole number >= ``least`` (plain ASCII digits: no sign, no exponent)."""

    def parse(text: str) -> int:
        # str.isdigit alone lets through digits int() refuses, such as superscripts
        if not (text.isascii() and text.isdigit()) or int(text) < least:
            raise argparse.ArgumentTypeError(f"expected an integer >= {least}, got {text!r}")
        return int(text)

    parse.__name__ = f"integer >= {least}"  # argparse names the type in some messages
    return parse


positive_int = at_least(1)
index = at_least(0)
seed = at_least(0)  # numpy's generators refuse a negative seed (with a traceback)
