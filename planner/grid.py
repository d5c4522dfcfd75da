"""Grid model: coarse cells from sub-cells, 4-connected components, and the work-area.

Component labelling is our own numpy routine (hook and shortcut, below) rather than
scipy.sparse.csgraph.connected_components: importing scipy.sparse.csgraph costs 31 MB (24 MB
more in an agent process, against an 80 MB budget), and the offline agent's planning path needs
nothing else from scipy. The tests keep scipy's connected_components as the oracle.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planner.errors import DisconnectedRobotsError, EmptyMapError, RobotPlacementError
from planner.types import BoolArray, CoarseGrid, IntArray, OccupancyGrid, SubCell

FAR = 1 << 40  # the distance of a cell no walk reaches


def breadth_first(open_cells: BoolArray, sources: BoolArray) -> IntArray:
    """Moves from the nearest of ``sources`` to every cell of ``open_cells`` over
    4-adjacent open cells (FAR where none leads), one whole-array step per move."""
    dist = np.full(open_cells.shape, FAR, dtype=np.int64)
    frontier = np.asarray(sources, dtype=bool).copy()
    dist[frontier] = 0
    step = 0
    while frontier.any():
        step += 1
        grown = np.zeros_like(frontier)
        grown[1:, :] |= frontier[:-1, :]
        grown[:-1, :] |= frontier[1:, :]
        grown[:, 1:] |= frontier[:, :-1]
        grown[:, :-1] |= frontier[:, 1:]
        frontier = grown & open_cells & (dist == FAR)
        dist[frontier] = step
    return dist


def coarsen(grid: OccupancyGrid) -> CoarseGrid:
    """Free coarse cells: a cell is free only if its 2 x 2 sub-cells are all free.

    An odd last row or column of sub-cells belongs to no whole cell and is dropped.
    """
    h, w = grid.shape
    fine = grid.free[: h - h % 2, : w - w % 2]
    blocks = fine.reshape(h // 2, 2, w // 2, 2)
    return CoarseGrid(np.asarray(blocks.all(axis=(1, 3)), dtype=np.bool_))


def label_components(free: BoolArray) -> tuple[IntArray, int]:
    """4-connected component labels (0 = blocked, 1..count in row-major order of first cell)."""
    free = np.asarray(free, dtype=bool)
    right = np.zeros(free.shape, dtype=bool)
    down = np.zeros(free.shape, dtype=bool)
    right[:, :-1] = free[:, :-1] & free[:, 1:]
    down[:-1, :] = free[:-1, :] & free[1:, :]
    return label_linked(free, right, down)


def label_linked(cells: BoolArray, right: BoolArray, down: BoolArray) -> tuple[IntArray, int]:
    """Component labels of ``cells`` when neighbours are joined only by the given edges.

    ``right[r, c]`` joins (r, c) to (r, c + 1) and ``down[r, c]`` joins (r, c) to (r + 1, c),
    as in SpanningTree; an edge with an end outside ``cells`` is ignored. Labels are as in
    label_components: 0 outside ``cells``, 1..count in row-major order of each part's first cell.
    """
    cells = np.asarray(cells, dtype=bool)
    h, w = cells.shape
    flat = np.arange(h * w, dtype=np.int64).reshape(h, w)
    across = np.asarray(right, dtype=bool)[:, :-1] & cells[:, :-1] & cells[:, 1:]
    below = np.asarray(down, dtype=bool)[:-1, :] & cells[:-1, :] & cells[1:, :]
    first = np.concatenate([flat[:, :-1][across], flat[:-1, :][below]])
    second = np.concatenate([flat[:, 1:][across], flat[1:, :][below]])
    root = _smallest_in_component(h * w, first, second)
    # A part's root is its smallest flat index, i.e. its first cell in row-major order, so
    # numbering the roots 1..count in index order gives the documented order.
    is_root = cells.ravel() & (root == np.arange(h * w))
    number = np.cumsum(is_root)
    labels = np.where(cells.ravel(), number[root], 0)
    return labels.reshape(h, w), int(number[-1]) if number.size else 0


def _smallest_in_component(size: int, first: IntArray, second: IntArray) -> IntArray:
    """For each node 0..size-1, the smallest node connected to it by the edges first-second.

    Hook and shortcut, as in Shiloach and Vishkin's parallel algorithm, in whole-array numpy
    steps instead of a Python loop over cells (40 000 cells: a few ms). Every parent is at most
    its node, so the parent links form trees rooted at their smallest node. Each round hooks
    every root that has an edge into another tree under the smallest root it touches, then
    jumps pointers until every node points at its root; rounds repeat until no edge joins two
    trees. A round removes at least the largest root of every split component; on 200 x 200
    mazes, corridors and random grids it takes 1-6 rounds.
    """
    parent = np.arange(size, dtype=np.int64)
    while True:
        a, b = parent[first], parent[second]
        split = a != b
        if not split.any():
            return parent
        low = np.minimum(a[split], b[split])
        high = np.maximum(a[split], b[split])
        np.minimum.at(parent, high, low)
        while True:
            grand = parent[parent]
            if np.array_equal(grand, parent):
                break
            parent = grand


def expand(cells: BoolArray) -> BoolArray:
    """Sub-cell mask of a cell mask (each cell becomes its 2 x 2 block)."""
    return np.repeat(np.repeat(cells, 2, axis=0), 2, axis=1)


@dataclass(frozen=True, eq=False)
class WorkArea:
    """The cells the robots must cover: the free component holding the robots' starts."""

    grid: OccupancyGrid
    coarse: CoarseGrid
    cells: BoolArray
    starts: tuple[SubCell, ...]

    @property
    def cell_count(self) -> int:
        return int(self.cells.sum())

    @property
    def sub_cells(self) -> BoolArray:
        """Sub-cells to cover, with the fine grid's shape (odd edge rows/cols False)."""
        h, w = self.grid.shape
        out = np.zeros((h, w), dtype=bool)
        mask = expand(self.cells)
        out[: mask.shape[0], : mask.shape[1]] = mask
        return out

    @property
    def n(self) -> int:
        return 4 * self.cell_count


def validate_starts(grid: OccupancyGrid, coarse: CoarseGrid,
                    starts: Sequence[SubCell]) -> None:
    """Raise a specific RobotPlacementError for the first bad start, naming the robot."""
    h, w = grid.shape
    seen: dict[SubCell, int] = {}
    for robot, (r, c) in enumerate(starts):
        if not (0 <= r < h and 0 <= c < w):
            raise RobotPlacementError(
                f"robot {robot} starts at ({r}, {c}), outside the {h} x {w} sub-cell map")
        if not grid.free[r, c]:
            raise RobotPlacementError(f"robot {robot} starts on an obstacle at ({r}, {c})")
        cr, cc = r // 2, c // 2
        if cr >= coarse.shape[0] or cc >= coarse.shape[1] or not coarse.free[cr, cc]:
            raise RobotPlacementError(
                f"robot {robot} starts at ({r}, {c}), in cell ({cr}, {cc}) which is discarded "
                "because one of its 2 x 2 sub-cells is blocked (or it lies on the map's odd "
                "last row/column)")
        if (r, c) in seen:
            raise RobotPlacementError(
                f"robots {seen[(r, c)]} and {robot} both start at ({r}, {c})")
        seen[(r, c)] = robot


def work_area(grid: OccupancyGrid, starts: Sequence[SubCell]) -> WorkArea:
    """The component of free cells that holds every robot's start.

    Offline MSTC needs one cycle through the whole work-area, so robots in different
    components are an error (DisconnectedRobotsError) rather than a partial plan; cells
    unreachable from the robots are left out of the work-area (they cannot be covered).
    """
    coarse = coarsen(grid)
    if coarse.cell_count == 0:
        raise EmptyMapError(
            f"{grid.name}: no free cell — a cell is free only if all four of its sub-cells "
            f"are free, and none of the {coarse.shape[0]} x {coarse.shape[1]} cells is")
    if not starts:
        raise RobotPlacementError("no robots given")
    validate_starts(grid, coarse, starts)
    labels, _ = label_components(coarse.free)
    label_of = [int(labels[r // 2, c // 2]) for r, c in starts]
    if len(set(label_of)) > 1:
        groups: dict[int, list[int]] = {}
        for robot, label in enumerate(label_of):
            groups.setdefault(label, []).append(robot)
        described = "; ".join(
            f"robots {members} in a component of {int((labels == label).sum())} cells"
            for label, members in groups.items())
        raise DisconnectedRobotsError(
            f"robots start in {len(groups)} disconnected parts of the map: {described}")
    cells = labels == label_of[0]
    return WorkArea(grid=grid, coarse=coarse, cells=cells, starts=tuple(starts))


def largest_component(coarse: CoarseGrid) -> BoolArray:
    """Mask of the largest 4-connected component of free cells (all False if none)."""
    labels, count = label_components(coarse.free)
    if count == 0:
        return np.zeros(coarse.shape, dtype=bool)
    sizes = np.bincount(labels.ravel())[1:]
    return labels == (int(np.argmax(sizes)) + 1)
