"""Robot start placements for TMSTC* experiments: spread evenly, or uniformly at random.

"Evenly" (the paper places robots "distributed evenly in the configuration space") is read as
k-means on the free cells' centres: scipy.cluster.vq.kmeans2 (seeded k-means++ start, then
Lloyd iterations), each robot on the free cell nearest its cluster centre.
"""

from __future__ import annotations

import numpy as np
from scipy.cluster.vq import kmeans2

from planner.errors import RobotPlacementError
from planner.types import BoolArray, SubCell


def _check(cells: BoolArray, k: int) -> np.ndarray:
    free = np.argwhere(cells)
    if k < 1:
        raise RobotPlacementError(f"need at least one robot, got {k}")
    if len(free) < k:
        raise RobotPlacementError(f"cannot place {k} robots on {len(free)} free cells")
    return free


def even_starts(cells: BoolArray, k: int, *, seed: int = 0) -> tuple[SubCell, ...]:
    """k robots on distinct free cells spread by k-means; each at its cell's top-left."""
    free = _check(cells, k)
    points = free.astype(np.float64)
    centres, _ = kmeans2(points, k, minit="++", seed=seed)
    taken: set[int] = set()
    out: list[SubCell] = []
    for centre in centres:
        order = np.argsort(((points - centre) ** 2).sum(axis=1), kind="stable")
        pick = next(int(i) for i in order if int(i) not in taken)
        taken.add(pick)
        out.append((2 * int(free[pick][0]), 2 * int(free[pick][1])))
    return tuple(out)


def random_starts(cells: BoolArray, k: int, *, seed: int = 0) -> tuple[SubCell, ...]:
    """k distinct sub-cells of the free cells, uniformly at random from ``seed``."""
    _check(cells, k)
    subs = np.argwhere(np.repeat(np.repeat(cells, 2, axis=0), 2, axis=1))
    rng = np.random.default_rng(seed)
    chosen = rng.choice(len(subs), size=k, replace=False)
    return tuple((int(subs[i][0]), int(subs[i][1])) for i in chosen)
