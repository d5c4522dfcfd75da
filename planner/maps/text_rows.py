"""Rows of one character per sub-cell, shared by the plain ASCII and Moving AI formats."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planner.errors import MapFormatError
from planner.types import BoolArray


def split_lines(text: str) -> list[str]:
    """Lines without their end-of-line or trailing spaces/tabs (no phantom last line)."""
    lines = [line.rstrip(" \t\r") for line in text.split("\n")]
    if lines and lines[-1] == "" and text.endswith("\n"):
        lines.pop()
    return lines


def drop_trailing_blank(lines: list[str]) -> list[str]:
    end = len(lines)
    while end > 0 and lines[end - 1] == "":
        end -= 1
    return lines[:end]


def parse_rows(rows: Sequence[str], first_line: int, width: int, free_chars: str,
               blocked_chars: str, source: str, width_from: str) -> BoolArray:
    """Check every row's length and characters, then return the free mask.

    ``first_line`` is the 1-based file line of ``rows[0]``, so errors point into the file;
    ``width_from`` says where the expected width comes from.
    """
    allowed = set(free_chars) | set(blocked_chars)
    for i, row in enumerate(rows):
        line = first_line + i
        if len(row) != width:
            raise MapFormatError(
                source, f"row has {len(row)} characters, expected {width} ({width_from})",
                line=line)
        if set(row) <= allowed:
            continue
        for col, char in enumerate(row, start=1):
            if char not in allowed:
                raise MapFormatError(
                    source, f"unknown character {char!r}; expected one of "
                    f"free {free_chars!r} or blocked {blocked_chars!r}", line=line, column=col)
    if not rows:
        return np.zeros((0, width), dtype=bool)
    codes = np.frombuffer("".join(rows).encode("ascii"), dtype=np.uint8)
    free = np.isin(codes, np.frombuffer(free_chars.encode("ascii"), dtype=np.uint8))
    return free.reshape(len(rows), width)
