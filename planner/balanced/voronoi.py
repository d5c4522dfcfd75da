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
from scipy.sparse import coo_matrix, csr_matrix
from scipy.sparse.csgraph import dijkstra, shortest_path

from planner.balanced.state import UNCLAIMED, PartitionState
from planner.types import Int32Array, IntArray

ITERATIONS = 300
STEP = 0.5
DECAY = 0.98
_UNREACHABLE = 1 << 30
TIE = 1e-9  # per robot index: breaks exact ties towards the lowest robot (_Owners)
MANY = 48  # robots from which the owners come from a Dijkstra (_Owners), not a k x N argmin
_CHUNK = 128  # sources per shortest_path call: bounds the float64 block it returns


def voronoi_labels(state: PartitionState) -> IntArray:
    """Robot per free cell (-1 where no robot can reach), balanced by weights; claims nothing."""
    robots = [r for r in range(state.k) if state.whole[r]]
    labels = np.full(len(state.free), -1, dtype=np.int64)
    if not robots:
        return labels
    open_cells = [u for u, lab in enumerate(state.label)
                  if state.free[u] and (lab == UNCLAIMED or lab >= 0)]
    seeds = [min(state.whole[r]) for r in robots]
    if len(robots) > MANY:
        owners = _Owners(state, open_cells, seeds)
        cols, argmin = owners.cols, owners.argmin
    else:
        dist = _distances(state, open_cells, seeds)
        reach = dist.min(axis=0) < _UNREACHABLE
        cols = np.asarray(open_cells, dtype=np.int64)[reach]
        # cells x robots, contiguous per cell: the argmin over a cell's robots is the inner loop
        dist_t = np.ascontiguousarray(dist[:, reach].T, dtype=np.float64)
        del dist
        shifted = np.empty_like(dist_t)

        def argmin(weights: np.ndarray) -> IntArray:
            np.add(dist_t, weights, out=shifted)
            return shifted.argmin(axis=1)
    target = len(cols) / len(robots)
    cap = int(np.ceil(target))
    scale = max(1.0, float(np.sqrt(target)))
    weights = np.zeros(len(robots))
    best: tuple[int, IntArray] | None = None
    step = STEP
    for _ in range(ITERATIONS):
        owner = argmin(weights)
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


class _Owners:
    """The owner of each reachable cell, argmin over robots of dist + weight, for many robots.

    That argmin is where a multi-source Dijkstra reaches a cell first when robot i's seed
    starts at its weight: a virtual node per robot, one edge of weight ``w_i - min w + 1``
    to its seed, the grid's unit edges, and scipy's ``dijkstra(min_only=True)`` naming the
    source that reaches each cell. No k x N distance array (94 MB per copy at k = 1000 on
    the issue's 47 000-sub-cell map) and no k x N pass per weight iteration; exact but for
    ties, which go by Dijkstra's order instead of the lowest robot.
    """

    def __init__(self, state: PartitionState, cells: list[int], seeds: list[int]) -> None:
        position = np.full(len(state.free), -1, dtype=np.int64)
        position[cells] = np.arange(len(cells))
        src = position[state.edge_src]
        dst = position[state.edge_dst]
        inside = (src >= 0) & (dst >= 0)
        m, k = len(cells), len(seeds)
        self.m = m
        virtual = np.arange(m, m + k)
        rows = np.concatenate([src[inside], virtual])
        heads = np.concatenate([dst[inside], position[seeds]])
        graph = csr_matrix((np.ones(rows.size), (rows, heads)), shape=(m + k, m + k))
        graph.sort_indices()
        # CSR orders entries by row: the k virtual rows come last, one entry each
        self.graph = graph
        self.virtual = virtual
        self.ties = TIE * np.arange(k, dtype=np.float64)
        reached = self._sources(np.zeros(k))
        self.reach = reached >= 0
        self.cols = np.asarray(cells, dtype=np.int64)[self.reach]

    def _sources(self, weights: np.ndarray) -> IntArray:
        # + TIE x robot: equal values go to the lowest robot, as in the dense argmin
        self.graph.data[-len(weights):] = weights - weights.min() + 1.0 + self.ties
        _, _, sources = dijkstra(self.graph, indices=self.virtual, min_only=True,
                                 return_predecessors=True)
        found = np.asarray(sources[: self.m], dtype=np.int64)
        return np.where(found >= self.m, found - self.m, -1)

    def argmin(self, weights: np.ndarray) -> IntArray:
        return self._sources(weights)[self.reach]


def _distances(state: PartitionState, cells: list[int], seeds: list[int]) -> Int32Array:
    """Breadth-first distances (k x len(cells), int32) from each seed over the given cells."""
    position = np.full(len(state.free), -1, dtype=np.int64)
    position[cells] = np.arange(len(cells))
    src = position[state.edge_src]
    dst = position[state.edge_dst]
    inside = (src >= 0) & (dst >= 0)
    m = len(cells)
    graph = coo_matrix((np.ones(int(inside.sum())), (src[inside], dst[inside])),
                       shape=(m, m)).tocsr()
    sources = position[seeds].tolist()
    out = np.empty((len(sources), m), dtype=np.int32)
    for at in range(0, len(sources), _CHUNK):
        found = shortest_path(graph, unweighted=True, indices=sources[at:at + _CHUNK])
        found[~np.isfinite(found)] = _UNREACHABLE
        out[at:at + _CHUNK] = found
    return out


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
