"""The work left after a death, partitioned anew from where the survivors stand (issue 14,
item 2; one of the re-plans planner.offline.rebalance compares).

The re-plans that keep each survivor's route make the survivors walk to the dead robot's
region after their own work (10-40 moves on the office map). Here the cells still holding
uncovered sub-cells are cut into balanced connected regions grown from the survivors'
positions (planner.balanced.regions.partition, the fleet plan's own partitioner), so the
survivors next to the orphans take them and hand their own far work to their neighbours.
Each survivor's work is its region's uncovered sub-cells in the order of the region's STC
walk. Cells with no uncovered sub-cell are left out except where they join the rest into
one area (the walk across them costs one move per sub-cell, not four).

The partitioner counts every sub-cell of a cell, covered or not, so a region of many
half-covered cells holds less work than its size says: ``offsets`` (moves per survivor,
the partitioner's own input) correct that on later calls (planner.offline.rebalance).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planner.balanced.coverage import region_path
from planner.balanced.regions import partition
from planner.errors import RobotPlacementError
from planner.grid import FAR, breadth_first, expand, label_components, work_area
from planner.types import BoolArray, Cycle, IntArray, OccupancyGrid


@dataclass(frozen=True)
class RegrownWork:
    """Per survivor (in the order of the positions given): its region's size in sub-cells
    and the uncovered cycle indices of that region in walk order."""

    sizes: tuple[int, ...]
    work: tuple[tuple[int, ...], ...]


def regrown_work(cycle: Cycle, covered: BoolArray, positions: Sequence[int],
                 offsets: Sequence[int] | None = None, *, seed: int = 0) -> RegrownWork | None:
    """Balanced regions of the uncovered work grown from ``positions`` (cycle indices, one
    per survivor; ``covered`` per cycle index). None when no such partition exists: two
    survivors on one sub-cell, or start cells walling off part of the work."""
    cells = _remaining_cells(cycle, covered, positions)
    h, w = cycle.index.shape
    free = np.zeros((h, w), dtype=bool)
    fine = expand(cells)
    free[: fine.shape[0], : fine.shape[1]] = fine
    starts = [cycle.at(p) for p in positions]
    try:
        area = work_area(OccupancyGrid(free, name="remaining work"), starts)
    except RobotPlacementError:
        return None
    parts = partition(area, seed=seed, offsets=offsets)
    if parts is None:
        return None
    taken = covered.copy()
    work = []
    for region in parts.regions:
        order = []
        for sub in region_path(region, seed=seed):
            index = cycle.position(sub)
            if not taken[index]:
                taken[index] = True
                order.append(index)
        work.append(tuple(order))
    return RegrownWork(parts.sizes, tuple(work))


def _remaining_cells(cycle: Cycle, covered: BoolArray, positions: Sequence[int]) -> BoolArray:
    """Cells with an uncovered sub-cell or a survivor on them, joined into one component
    through the fewest other cells of the cycle's area."""
    h, w = cycle.index.shape[0] // 2, cycle.index.shape[1] // 2
    index = cycle.index[: 2 * h, : 2 * w]
    on_cycle: BoolArray = np.asarray((index >= 0).reshape(h, 2, w, 2).all(axis=(1, 3)))
    left = np.zeros(index.shape, dtype=bool)
    left[index >= 0] = ~covered[index[index >= 0]]
    cells: BoolArray = np.asarray(left.reshape(h, 2, w, 2).any(axis=(1, 3))) & on_cycle
    for p in positions:
        r, c = cycle.at(p)
        cells[r // 2, c // 2] = True
    labels, count = label_components(cells)
    while count > 1:
        _join_nearest(cells, labels, on_cycle)
        labels, count = label_components(cells)
    return cells


def _join_nearest(cells: BoolArray, labels: IntArray, on_cycle: BoolArray) -> None:
    """Add to ``cells`` a shortest chain of ``on_cycle`` cells from component 1 to the
    nearest other component (ties by cell order)."""
    dist = breadth_first(on_cycle, labels == 1)
    others = np.where(labels > 1, dist, FAR)
    r, c = (int(x) for x in np.unravel_index(int(np.argmin(others)), others.shape))
    assert others[r, c] < FAR, "the cells of one cycle form one component"
    while dist[r, c] > 1:
        r, c = next((nr, nc) for nr, nc in ((r - 1, c), (r, c + 1), (r + 1, c), (r, c - 1))
                    if 0 <= nr < dist.shape[0] and 0 <= nc < dist.shape[1]
                    and dist[nr, nc] == dist[r, c] - 1)
        cells[r, c] = True
