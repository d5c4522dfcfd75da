"""First regions: an additively weighted geodesic Voronoi partition, weights tuned to balance.

Cell c goes to the robot minimising ``dist_i(c) + w_i`` (dist: breadth-first distance from
the robot's seed cell over the free cells, scipy.sparse.csgraph, all robots in one call).
With additive weights every region is connected: the cell before c on a shortest path from
robot i's seed is at least as close to i, relative to every other robot, as c is. Raising
the weight of a too-large region shrinks it, so a few hundred vectorised numpy iterations
(one argmin over a k x N array each) get the sizes close to balanced; the transfer step
(balance.py) finishes the job cell by cell. This is DARP's idea with a distance that keeps
regions connected by construction, which is why it cannot fail to converge the way DARP can.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import shortest_path

from planner.balanced.state import UNCLAIMED, PartitionState
from planner.types import IntArray

ITERATIONS = 300
STEP = 0.5
DECAY = 0.98
_UNREACHABLE = 1 << 30


def voronoi_labels(state: PartitionState) -> IntArray:
    """Robot per free cell (-1 where no robot can reach), balanced by weights; claims nothing."""
    robots = [r for r in range(state.k) if state.whole[r]]
    labels = np.full(len(state.free), -1, dtype=np.int64)
    if not robots:
        return labels
    open_cells = [u for u, lab in enumerate(state.label)
                  if state.free[u] and (lab == UNCLAIMED or lab >= 0)]
    dist = _distances(state, open_cells, [min(state.whole[r]) for r in robots])
    free_cols = np.asarray(open_cells, dtype=np.int64)
    reach = dist.min(axis=0) < _UNREACHABLE
    cols = free_cols[reach]
    # cells x robots, contiguous per cell: the argmin over a cell's robots is the inner loop
    dist_t = np.ascontiguousarray(dist[:, reach].T, dtype=np.float64)
    shifted = np.empty_like(dist_t)
    target = len(cols) / len(robots)
    cap = int(np.ceil(target))
    scale = max(1.0, float(np.sqrt(target)))
    weights = np.zeros(len(robots))
    best: tuple[int, IntArray] | None = None
    step = STEP
    for _ in range(ITERATIONS):
        np.add(dist_t, weights, out=shifted)
        owner = shifted.argmin(axis=1)
        sizes = np.bincount(owner, minlength=len(robots))
        worst = int(sizes.max())
        if best is None or worst < best[0]:
            best = (worst, owner)
        if worst <= cap:
            break
        weights += step * scale * (sizes - target) / target
        step *= DECAY
    assert best is not None
    labels[cols] = np.asarray(robots, dtype=np.int64)[best[1]]
    return labels


def _distances(state: PartitionState, cells: list[int], seeds: list[int]) -> IntArray:
    """Breadth-first distances (k x len(cells)) from each seed over the given cells."""
    position = np.full(len(state.free), -1, dtype=np.int64)
    position[cells] = np.arange(len(cells))
    src = position[state.edge_src]
    dst = position[state.edge_dst]
    inside = (src >= 0) & (dst >= 0)
    m = len(cells)
    graph = coo_matrix((np.ones(int(inside.sum())), (src[inside], dst[inside])),
                       shape=(m, m)).tocsr()
    found = shortest_path(graph, unweighted=True, indices=position[seeds].tolist())
    found[~np.isfinite(found)] = _UNREACHABLE
    return found.astype(np.int64)


def adopt(state: PartitionState, labels: IntArray) -> None:
    """Claim for each robot the cells labelled for it that connect to its region."""
    for robot in range(state.k):
        frontier = list(state.whole[robot])
        while frontier:
            u = frontier.pop()
            for v in state.neighbours[u]:
                if state.label[v] == UNCLAIMED and labels[v] == robot:
                    state.claim(robot, v)
                    frontier.append(v)
