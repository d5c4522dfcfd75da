"""The plain aliases every message module shares.

Conventions: robots are ints; a pose is (row, col, heading) in sub-cells with heading
numbered as planner.geometry.Heading (0=N 1=E 2=S 3=W); ``sim_time`` is simulated seconds;
``incarnation`` grows each time a robot's process (re)starts so that stale lives can be
fenced.
"""

import zlib

from planner.geometry import Cell as Cell
from planner.geometry import SubCell as SubCell

Pose = tuple[int, int, int]  # planner.geometry.Pose.as_tuple(), as it travels
SummaryValue = int | float | str


def inflate(data: bytes, limit: int) -> bytes:
    """zlib-decompress at most ``limit`` bytes of ``data``; ValueError if it is not zlib."""
    try:
        return zlib.decompressobj().decompress(data, max(limit, 1))
    except zlib.error as error:
        raise ValueError(f"packed array does not decompress: {error}") from error
