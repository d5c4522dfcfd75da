"""Value types of the balanced planner: leaf cells, regions and the partition.

A region is a connected set of whole cells (each 2 x 2 sub-cells) plus *leaf cells*: cells
hung off one whole cell of the region (their anchor) of which the region keeps only some
sub-cells. Leaves give the partition a granularity of 2 sub-cells (half cells) and let two
robots that start in the same cell share it.
"""

from __future__ import annotations

from dataclasses import dataclass

from planner.types import Cell, SubCell


@dataclass(frozen=True)
class LeafCell:
    """Sub-cells ``subs`` of cell ``cell``, reached from whole cell ``anchor`` of the region.

    ``anchor`` is None only for a region with no whole cell at all (a robot boxed in by
    other robots' start cells): then the region is this leaf alone.
    """

    cell: Cell
    anchor: Cell | None
    subs: tuple[SubCell, ...]


@dataclass(frozen=True)
class Region:
    """What one robot covers: whole ``cells`` (4-connected) plus ``leaves``; ``start`` in it."""

    robot: int
    start: SubCell
    cells: tuple[Cell, ...]
    leaves: tuple[LeafCell, ...]

    @property
    def size(self) -> int:
        """Sub-cells in the region (its robot needs size - 1 moves)."""
        return 4 * len(self.cells) + sum(len(leaf.subs) for leaf in self.leaves)


@dataclass(frozen=True)
class Partition:
    """One region per robot, in robot-id order; together they tile the work-area's sub-cells."""

    regions: tuple[Region, ...]
    transfers: int = 0

    @property
    def sizes(self) -> tuple[int, ...]:
        return tuple(region.size for region in self.regions)
