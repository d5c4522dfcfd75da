"""Value types of TMSTC*: brick tilings and time-balanced divisions of the STC cycle."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.types import BoolArray, IntArray, SubCell


def _frozen(array: np.ndarray) -> np.ndarray:
    array = np.ascontiguousarray(array)
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class BrickTiling:
    """A tiling of the free cells by straight bricks (1 x L or L x 1 runs of cells).

    ``right``/``down`` are the removed borders (edges inside bricks) in the layout of
    :class:`planner.types.SpanningTree`; ``brick[r, c]`` numbers the brick of each free cell
    (-1 elsewhere), 0..count-1.
    """

    cells: BoolArray
    right: BoolArray
    down: BoolArray
    brick: IntArray
    count: int

    def __post_init__(self) -> None:
        for name in ("cells", "right", "down", "brick"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))


@dataclass(frozen=True)
class RobotRoute:
    """One robot's TMSTC* route: travel from its start to ``first``, then cover to ``last``.

    ``first`` and ``last`` are cycle indices (the covered stretch runs counter-clockwise and
    may wrap); ``path`` is every sub-cell visited, start included; ``time`` is eq. 8 seconds.
    """

    robot: int
    start: SubCell
    first: int
    covered: int
    travel: int
    path: tuple[SubCell, ...]
    time: float


@dataclass(frozen=True)
class Division:
    """A split of the STC cycle into one contiguous stretch per robot (robot-id order)."""

    balance: str
    routes: tuple[RobotRoute, ...]

    @property
    def makespan_time(self) -> float:
        return max((r.time for r in self.routes), default=0.0)

    @property
    def min_time(self) -> float:
        return min((r.time for r in self.routes), default=0.0)
