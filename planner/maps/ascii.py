"""Plain ASCII maps: one character per sub-cell, ``.`` free, ``#`` or ``@`` blocked."""

from __future__ import annotations

from planner.errors import MapFormatError
from planner.maps.text_rows import drop_trailing_blank, parse_rows, split_lines
from planner.types import OccupancyGrid

FREE = "."
BLOCKED = "#@"


def parse_ascii(text: str, source: str = "<string>", name: str | None = None) -> OccupancyGrid:
    """The grid drawn in ``text``; errors name ``source`` and the line (and column)."""
    rows = drop_trailing_blank(split_lines(text))
    if not rows:
        raise MapFormatError(source, "empty map: no rows")
    if rows[0] == "":
        raise MapFormatError(source, "first row is blank; expected a row of '.', '#' or '@'",
                             line=1)
    free = parse_rows(rows, 1, len(rows[0]), FREE, BLOCKED, source,
                      "the first row's length")
    return OccupancyGrid(free, name=name if name is not None else source)
