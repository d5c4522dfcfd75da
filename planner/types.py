"""Value types shared by the planner: grids, trees, cycles, allocations and plans.

Coordinates are (row, col), row growing downwards as in images and map files. A *sub-cell* is
one tool-sized square of the fine grid; a *cell* is the 2 x 2 block of sub-cells
(2r..2r+1, 2c..2c+1). All arrays are numpy arrays owned by the value and never mutated after
construction (the dataclasses are frozen; the arrays are made read-only).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np
import numpy.typing as npt

# planner.geometry's, re-exported beside the value types that use them
from planner.geometry import Cell as Cell
from planner.geometry import SubCell as SubCell

BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int64]
Int32Array = npt.NDArray[np.int32]  # large distance tables (half the memory of IntArray)


def _frozen(array: npt.NDArray[np.generic]) -> npt.NDArray[np.generic]:
    array = np.ascontiguousarray(array)
    array.setflags(write=False)
    return array


@dataclass(frozen=True, eq=False)
class OccupancyGrid:
    """The fine grid: ``free[r, c]`` is True when sub-cell (r, c) holds no obstacle."""

    free: BoolArray
    name: str = "map"

    def __post_init__(self) -> None:
        if self.free.ndim != 2 or self.free.dtype != np.bool_:
            raise ValueError("OccupancyGrid.free must be a 2-D bool array")
        object.__setattr__(self, "free", _frozen(self.free))

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.free.shape[0]), int(self.free.shape[1]))


@dataclass(frozen=True, eq=False)
class CoarseGrid:
    """Free coarse cells: a cell is free only if all four of its sub-cells are."""

    free: BoolArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "free", _frozen(self.free))

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.free.shape[0]), int(self.free.shape[1]))

    @property
    def cell_count(self) -> int:
        return int(self.free.sum())


@dataclass(frozen=True, eq=False)
class SpanningTree:
    """A spanning tree over the free cells of one component.

    ``right[r, c]`` is the edge (r, c)-(r, c+1); ``down[r, c]`` the edge (r, c)-(r+1, c). Both
    have the coarse grid's shape (the last column of ``right`` and last row of ``down`` are
    always False). ``cells`` marks the cells the tree spans.
    """

    cells: BoolArray
    right: BoolArray
    down: BoolArray

    def __post_init__(self) -> None:
        for name in ("cells", "right", "down"):
            object.__setattr__(self, name, _frozen(getattr(self, name)))

    @property
    def cell_count(self) -> int:
        return int(self.cells.sum())

    @property
    def edge_count(self) -> int:
        return int(self.right.sum() + self.down.sum())

    def edges(self) -> list[tuple[Cell, Cell]]:
        """Every edge once, as ((r, c), (r2, c2)) with the second cell right of or below."""
        out: list[tuple[Cell, Cell]] = []
        for r, c in zip(*np.nonzero(self.right), strict=True):
            out.append(((int(r), int(c)), (int(r), int(c) + 1)))
        for r, c in zip(*np.nonzero(self.down), strict=True):
            out.append(((int(r), int(c)), (int(r) + 1, int(c))))
        return out


@dataclass(frozen=True, eq=False)
class Cycle:
    """The STC circumnavigation: a closed walk through every sub-cell of the tree's cells.

    ``path[i]`` is the (row, col) of the i-th sub-cell; the walk goes on from ``path[n-1]`` to
    ``path[0]``. Increasing index is the counter-clockwise direction (as drawn with rows going
    down). ``index[r, c]`` is the position of sub-cell (r, c) on the cycle, -1 when off it.
    """

    path: IntArray
    index: IntArray

    def __post_init__(self) -> None:
        object.__setattr__(self, "path", _frozen(self.path))
        object.__setattr__(self, "index", _frozen(self.index))

    @property
    def n(self) -> int:
        return int(self.path.shape[0])

    def position(self, sub: SubCell) -> int:
        """Index of ``sub`` on the cycle, or -1 when the sub-cell is not on it."""
        r, c = sub
        if not (0 <= r < self.index.shape[0] and 0 <= c < self.index.shape[1]):
            return -1
        return int(self.index[r, c])

    def at(self, i: int) -> SubCell:
        r, c = self.path[i % self.n]
        return (int(r), int(c))


class Direction(Enum):
    """Direction of travel along the cycle: CCW = increasing index."""

    CCW = "ccw"
    CW = "cw"

    @property
    def sign(self) -> int:
        return 1 if self is Direction.CCW else -1


@dataclass(frozen=True)
class Leg:
    """One straight run along the cycle: ``length`` moves in ``direction``."""

    direction: Direction
    length: int


@dataclass(frozen=True)
class RobotAllocation:
    """What one robot covers, in cycle-index space, before turning it into sub-cells.

    The robot covers its start, ``forward`` sub-cells ahead of it (CCW) and ``backward``
    sub-cells behind it (CW). ``legs`` is the walk that does it (a backtracking robot walks the
    first leg, returns over it, then walks the other side).
    """

    robot: int
    start_index: int
    forward: int
    backward: int
    legs: tuple[Leg, ...]

    @property
    def steps(self) -> int:
        return sum(leg.length for leg in self.legs)


@dataclass(frozen=True)
class RobotPlan:
    """One robot's part of a plan: the ordered sub-cells it visits, start included.

    ``walk_out`` counts the first moves of ``path`` that only lead the robot to its region
    (balanced plans); they cross sub-cells that other robots cover too.
    """

    robot: int
    start: SubCell
    start_index: int
    legs: tuple[Leg, ...]
    path: tuple[SubCell, ...]
    speed: float = 1.0
    walk_out: int = 0

    @property
    def steps(self) -> int:
        return len(self.path) - 1

    @property
    def time(self) -> float:
        return self.steps / self.speed


@dataclass(frozen=True, eq=False)
class Plan:
    """A complete offline plan: per robot (in robot-id order) its walk along the cycle."""

    algo: str
    cycle: Cycle
    robots: tuple[RobotPlan, ...]
    tree: SpanningTree | None = None
    notes: tuple[str, ...] = field(default=())

    @property
    def n(self) -> int:
        return self.cycle.n

    @property
    def k(self) -> int:
        return len(self.robots)

    @property
    def makespan(self) -> int:
        """Largest number of moves of any robot (the papers' coverage time)."""
        return max((r.steps for r in self.robots), default=0)

    @property
    def makespan_time(self) -> float:
        """Largest per-robot time, steps / speed (equals makespan for unit speeds)."""
        return max((r.time for r in self.robots), default=0.0)
