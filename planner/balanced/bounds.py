"""A lower bound on the makespan that counts the robots' walks (issue 14, item 3's benchmark).

``ceil(n/k) - 1`` assumes every robot covers a new sub-cell with every move from the start.
Where robots must first walk to anything they can cover alone (a maze's corridors), no plan
comes near it, and a table of "% over the bound" then measures the map, not the planner.

The flow bound. Take any plan with makespan T and give every sub-cell to the first robot
that covers it; robot j gets S_j. Robot j covers at most one new sub-cell per move, and a
sub-cell at breadth-first distance d from its start no earlier than move d. So S_j holds at
most T + 1 sub-cells, and at most T - t + 1 of them at distance t or more, for every
t >= 1. Those are capacities of a flow network: source -> each sub-cell (1) -> (j, d_j(v))
for every robot within reach (1) -> (j, d - 1) -> ... -> (j, 0) -> sink, the arc out of
(j, t) carrying the sub-cells at distance t or more (capacity T - t + 1; T + 1 into the
sink). A plan of makespan T is a flow of value n; so if the maximum flow is below n, no
plan finishes in T moves. Every capacity grows with T, so the smallest T with a full flow
is found by a search and bounds every plan from below, the regions, opt and the split alike.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import maximum_flow

from planner.balanced.assign import UNREACHABLE, start_distances
from planner.grid import WorkArea
from planner.types import IntArray


def _full_flow(walks: IntArray, bound: int) -> bool:
    """True if every sub-cell (a column of ``walks``) can be given a robot under ``bound``."""
    k, n = walks.shape
    band = 1 + n  # node of (robot j, distance t): band + j * (bound + 1) + t
    sink = band + k * (bound + 1)
    robot, sub = np.nonzero(walks <= bound)
    steps = np.arange(1, bound + 1)
    chain = (band + np.arange(k)[:, None] * (bound + 1) + steps[None, :]).ravel()
    tails = np.concatenate([np.zeros(n, dtype=np.int64), 1 + sub, chain,
                            band + np.arange(k) * (bound + 1)])
    heads = np.concatenate([1 + np.arange(n), band + robot * (bound + 1) + walks[robot, sub],
                            chain - 1, np.full(k, sink)])
    capacity = np.concatenate([np.ones(n + sub.size, dtype=np.int32),
                               np.tile(bound - steps + 1, k).astype(np.int32),
                               np.full(k, bound + 1, dtype=np.int32)])
    graph = csr_matrix((capacity, (tails, heads)), shape=(sink + 1, sink + 1))
    graph.sum_duplicates()
    return bool(maximum_flow(graph, 0, sink).flow_value >= n)


def flow_bound(area: WorkArea) -> int:
    """The smallest makespan the flow bound allows (at least ceil(n/k) - 1)."""
    sub = area.sub_cells
    w = sub.shape[1]
    rows, cols = np.nonzero(sub)
    walks = start_distances(area)[:, rows * w + cols].astype(np.int64)
    walks[walks >= UNREACHABLE] = np.iinfo(np.int64).max // 4
    k, n = walks.shape
    low = math.ceil(n / k) - 1  # below it even walks of length 0 do not do (flow <= k(T+1))
    if _full_flow(walks, low):
        return low
    step, high = 1, low + 1
    while not _full_flow(walks, high):  # the bound of one robot walking everything holds
        low, high, step = high, high + 2 * step, 2 * step
    while high - low > 1:
        mid = (low + high) // 2
        if _full_flow(walks, mid):
            high = mid
        else:
            low = mid
    return high
