"""Moving AI Lab ``.map`` files (Sturtevant 2012): a four-line header, then the rows.

``.``, ``G`` and ``S`` are passable; ``@``, ``O``, ``T`` (trees) and ``W`` (water) are not: a
ground robot's tool cannot sweep them.
"""

from __future__ import annotations

from planner.errors import MapFormatError
from planner.maps.text_rows import drop_trailing_blank, parse_rows, split_lines
from planner.types import BoolArray

FREE = ".GS"
BLOCKED = "@OTW"


def _field(lines: list[str], index: int, key: str, source: str) -> str:
    """The value of header line ``index``, which must read ``key <value>``."""
    line = lines[index] if index < len(lines) else None
    parts = line.split() if line is not None else []
    if len(parts) != 2 or parts[0] != key:
        got = "end of file" if line is None else repr(line)
        raise MapFormatError(source, f"expected '{key} <value>', got {got}", line=index + 1)
    return parts[1]


def _dimension(lines: list[str], index: int, key: str, source: str) -> int:
    value = _field(lines, index, key, source)
    if not value.isdigit() or int(value) == 0:
        raise MapFormatError(source, f"{key} must be a positive integer, got {value!r}",
                             line=index + 1)
    return int(value)


def parse_movingai(text: str, source: str) -> BoolArray:
    """Free mask of a Moving AI map; header or row errors name the line."""
    lines = split_lines(text)
    kind = _field(lines, 0, "type", source)
    if kind != "octile":
        raise MapFormatError(source, f"expected 'type octile', got 'type {kind}'", line=1)
    height = _dimension(lines, 1, "height", source)
    width = _dimension(lines, 2, "width", source)
    if len(lines) < 4 or lines[3] != "map":
        got = "end of file" if len(lines) < 4 else repr(lines[3])
        raise MapFormatError(source, f"expected 'map', got {got}", line=4)
    body = drop_trailing_blank(lines[4:])
    if len(body) < height:
        raise MapFormatError(
            source, f"expected {height} rows (height {height}), found {len(body)}",
            line=5 + len(body))
    if len(body) > height:
        raise MapFormatError(
            source, f"expected end of map after {height} rows (height {height})",
            line=5 + height)
    return parse_rows(body, 5, width, FREE, BLOCKED, source, f"width {width}")
