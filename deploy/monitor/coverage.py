"""Coverage as the wire shows it: visits per sub-cell, who entered each first and in which
order, what is reachable at all, and the coverage curve. Pure; fed by the fleet model."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

import numpy as np
import numpy.typing as npt

from planner.grid import coarsen, expand, label_components
from planner.types import BoolArray, OccupancyGrid, SubCell


def reachable_sub_cells(grid: OccupancyGrid, starts: tuple[SubCell, ...]) -> BoolArray:
    """Sub-cells of the free cells connected to some robot's start: what STC can cover.

    A sub-cell of a partly blocked cell is not reachable (a cell is free only if all four
    of its sub-cells are), and neither is a component no robot starts in.
    """
    coarse = coarsen(grid)
    labels, _ = label_components(coarse.free)
    h, w = labels.shape
    wanted = {int(labels[r // 2, c // 2]) for r, c in starts if r // 2 < h and c // 2 < w}
    wanted.discard(0)
    cells = np.isin(labels, sorted(wanted))
    out = np.zeros(grid.shape, dtype=bool)
    mask = expand(cells)
    out[: mask.shape[0], : mask.shape[1]] = mask
    return out


class CoverageMap:
    """Ground-truth coverage (simhw's CoverEvents and WorldState), with the agents' own
    Progress reports kept aside for missions without a simulator."""

    def __init__(self) -> None:
        self.map_name = ""
        self.free: BoolArray | None = None
        self.visits: dict[SubCell, int] = {}
        self.owner: dict[SubCell, int] = {}  # the robot that entered first, where known
        self.visitors: dict[SubCell, list[int]] = {}  # robots of each visit seen, in order
        # entries each robot announced as made only to sense (LookStep), per sub-cell
        self.looks: dict[SubCell, dict[int, int]] = {}
        self.reported: dict[SubCell, int] = {}
        # (t, sim_time, covered reachable sub-cells; all covered before the map is known)
        self.curve: list[tuple[float, float, int]] = []
        self.complete_at: tuple[float, float] | None = None
        self._reachable: BoolArray | None = None
        self._reachable_count = 0  # its sum, counted when it changes: asked at every cover
        self._tried: set[SubCell] = set()
        self._in_reach = 0
        self._counts: npt.NDArray[np.int64] | None = None  # visits as an array, once mapped

    def set_map(self, name: str, free: BoolArray) -> bool:
        """Take the map of a WorldState; True if it is new (or changed shape)."""
        if self.free is not None and self.free.shape == free.shape:
            return False
        self.map_name, self.free, self._reachable = name, free, None
        self._counts = np.zeros(free.shape, dtype=np.int64)
        for (r, c), n in self.visits.items():
            if 0 <= r < free.shape[0] and 0 <= c < free.shape[1]:
                self._counts[r, c] = n
        return True

    def newer_counts(self, counts: npt.NDArray[np.integer[Any]]) -> list[tuple[SubCell, int]]:
        """Sub-cells whose count in ``counts`` (a WorldState's) exceeds ours: a world answer
        every few seconds is merged in time proportional to what changed, not to the map."""
        if self._counts is None or self._counts.shape != counts.shape:
            return [((int(r), int(c)), int(counts[r, c])) for r, c in np.argwhere(counts > 0)]
        return [((int(r), int(c)), int(counts[r, c]))
                for r, c in np.argwhere(counts > self._counts)]

    def visit(self, robot: int, cell: SubCell, visits: int) -> bool:
        """A robot entered ``cell`` for the ``visits``-th time; False if already counted."""
        if visits <= len(self.visitors.get(cell, ())):
            return False
        self.visitors.setdefault(cell, []).append(robot)
        if visits == 1:
            self.owner.setdefault(cell, robot)
        return True

    def looked(self, robot: int, cell: SubCell) -> None:
        """``robot`` entered ``cell`` only to sense (its CoverEvent counts the visit too)."""
        per_robot = self.looks.setdefault(cell, {})
        per_robot[robot] = per_robot.get(robot, 0) + 1

    def set_visits(self, t: float, sim_time: float, cell: SubCell, count: int,
                   positions: Iterable[SubCell]) -> bool:
        """Raise the visit count of ``cell``; True if that completed the coverage."""
        if self.visits.get(cell, 0) >= count:
            return False
        # Reachability first: its recount must not see the cell that is about to count.
        reachable = self.reachable(positions)
        new = cell not in self.visits
        self.visits[cell] = count
        if self._counts is not None and 0 <= cell[0] < self._counts.shape[0] \
                and 0 <= cell[1] < self._counts.shape[1]:
            self._counts[cell] = count
        if not new:
            return False
        if reachable is not None and 0 <= cell[0] < reachable.shape[0] \
                and 0 <= cell[1] < reachable.shape[1] and reachable[cell]:
            self._in_reach += 1
        self.curve.append((t, sim_time, len(self.visits) if reachable is None
                           else self._in_reach))
        return self.check_complete(t, sim_time, positions)

    def check_complete(self, t: float, sim_time: float, positions: Iterable[SubCell]) -> bool:
        """True the first time every reachable sub-cell is covered."""
        total = self.total(positions)
        if self.complete_at is None and total and self._in_reach >= total:
            self.complete_at = (t, sim_time)
            return True
        return False

    def reachable(self, positions: Iterable[SubCell]) -> BoolArray | None:
        """Sub-cells STC can cover: free cells connected to a robot (None before the map
        and before any robot is seen)."""
        if self.free is None:
            return None
        h, w = self.free.shape
        fresh = {p for p in positions if 0 <= p[0] < h and 0 <= p[1] < w} - self._tried
        if not fresh and not self._tried:
            return None
        if self._reachable is None or any(not self._reachable[p] for p in fresh):
            # Only a robot seen in a new component changes the set: recompute rarely.
            self._tried |= fresh
            self._reachable = reachable_sub_cells(OccupancyGrid(self.free),
                                                  tuple(sorted(self._tried)))
            self._reachable_count = int(self._reachable.sum())
            self._in_reach = sum(1 for r, c in self.visits
                                 if 0 <= r < h and 0 <= c < w and self._reachable[r, c])
        else:
            self._tried |= fresh
        return self._reachable

    def covered_cells(self) -> dict[SubCell, int]:
        """Visit counts: ground truth if there is any, else the agents' reports."""
        return self.visits if self.visits or self.free is not None else self.reported

    def covered_count(self, positions: Iterable[SubCell]) -> int:
        """Covered sub-cells (reachable ones, once the map is known)."""
        if self.reachable(positions) is None or not self.visits:
            return len(self.covered_cells())
        return self._in_reach

    def total(self, positions: Iterable[SubCell]) -> int | None:
        reachable = self.reachable(positions)
        return None if reachable is None else self._reachable_count

    def revisits(self) -> int:
        """Visits beyond the first, over all sub-cells."""
        return sum(v - 1 for v in self.covered_cells().values() if v > 1)
