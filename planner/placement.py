"""Robot start placements: parsing user-given starts and seeded random placements."""

from __future__ import annotations

import numpy as np

from planner.errors import RobotPlacementError
from planner.grid import coarsen, expand, largest_component
from planner.types import OccupancyGrid, SubCell


def parse_starts(text: str) -> tuple[SubCell, ...]:
    """Parse ``"r,c;r,c;..."`` into sub-cell coordinates, with a readable error."""
    starts: list[SubCell] = []
    for number, item in enumerate(filter(None, (p.strip() for p in text.split(";")))):
        parts = [p.strip() for p in item.split(",")]
        if len(parts) != 2 or not all(p.lstrip("-").isdigit() for p in parts):
            raise RobotPlacementError(
                f"robot {number}: expected 'row,col' (two integers), got {item!r}")
        starts.append((int(parts[0]), int(parts[1])))
    if not starts:
        raise RobotPlacementError(f"no robot positions in {text!r}; expected 'r,c;r,c;...'")
    return tuple(starts)


def random_starts(grid: OccupancyGrid, k: int, seed: int, *,
                  one_per_cell: bool = False) -> tuple[SubCell, ...]:
    """``k`` distinct random sub-cells of the largest free component, from ``seed``; with
    ``one_per_cell`` (an algorithm whose robots need a coarse cell each, the registry's
    ``one_robot_per_cell``) no two in one coarse cell, so a launcher never draws starts its
    algorithm refuses."""
    if k < 1:
        raise RobotPlacementError(f"need at least one robot, got {k}")
    component = largest_component(coarsen(grid))
    rng = np.random.default_rng(seed)
    if one_per_cell:
        cells = np.argwhere(component)
        if len(cells) < k:
            raise RobotPlacementError(
                f"cannot place {k} robots one per cell: the largest free component has only "
                f"{len(cells)} cells")
        picked = rng.choice(len(cells), size=k, replace=False)
        offsets = rng.integers(2, size=(k, 2))
        return tuple((2 * int(cells[i][0]) + int(dr), 2 * int(cells[i][1]) + int(dc))
                     for i, (dr, dc) in zip(picked, offsets, strict=True))
    candidates = np.argwhere(expand(component))
    if len(candidates) < k:
        raise RobotPlacementError(
            f"cannot place {k} robots: the largest free component has only "
            f"{len(candidates)} sub-cells")
    chosen = rng.choice(len(candidates), size=k, replace=False)
    return tuple((int(candidates[i][0]), int(candidates[i][1])) for i in chosen)
