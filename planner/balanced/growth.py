"""Initial regions: seed every robot's start, then grow all regions smallest-first.

Growth is a multi-source breadth-first search in which the region with the fewest sub-cells
always claims next, taking its frontier cell nearest its seed (heapq, ties broken by the
seeded generator). Regions stay 4-connected by construction and end up nearly balanced
except where one is walled in by others; the transfer step (balance.py) fixes that.
"""

from __future__ import annotations

import heapq
import random
from collections import defaultdict

from planner.balanced.seeds import share_cell
from planner.balanced.state import SHARED, UNCLAIMED, PartitionState
from planner.balanced.types import LeafCell
from planner.geometry import cell_of
from planner.types import Cell


def seed_regions(state: PartitionState) -> None:
    """Claim and pin each start cell; divide cells where several robots start."""
    by_cell: dict[int, list[int]] = defaultdict(list)
    for robot, start in enumerate(state.starts):
        by_cell[state.flat(cell_of(start))].append(robot)
    for u, robots in by_cell.items():
        if len(robots) == 1:
            state.claim(robots[0], u)
            state.pin(u)

    def claimable(cell: Cell) -> bool:
        if not state.inside(cell):
            return False
        v = state.flat(cell)
        return state.label[v] == UNCLAIMED and v not in by_cell

    for u, robots in sorted(by_cell.items()):
        if len(robots) < 2:
            continue
        cell = state.cell(u)
        share = share_cell(cell, robots, state.starts, claimable)
        state.set_label(u, SHARED)
        for robot, keep, side in share.parts:
            anchor = None
            if side is not None:
                anchor = (cell[0] + side[0], cell[1] + side[1])
                state.claim(robot, state.flat(anchor))
                state.pin(state.flat(anchor))
            state.add_leaf(robot, LeafCell(cell=cell, anchor=anchor, subs=keep))


def grow(state: PartitionState, seed: int) -> None:
    """Claim every reachable unclaimed cell, the smallest region first."""
    rng = random.Random(seed)
    frontier: list[list[tuple[int, float, int]]] = [[] for _ in range(state.k)]
    queue: list[tuple[int, float, int]] = []
    for robot in range(state.k):
        for u in state.whole[robot]:
            _push_neighbours(state, frontier[robot], u, 1, rng)
        if frontier[robot]:
            queue.append((state.load[robot], rng.random(), robot))
    heapq.heapify(queue)
    while queue:
        _, _, robot = heapq.heappop(queue)
        heap = frontier[robot]
        while heap and state.label[heap[0][2]] != UNCLAIMED:
            heapq.heappop(heap)
        if not heap:
            continue
        dist, _, u = heapq.heappop(heap)
        state.claim(robot, u)
        _push_neighbours(state, heap, u, dist + 1, rng)
        heapq.heappush(queue, (state.load[robot], rng.random(), robot))


def _push_neighbours(state: PartitionState, heap: list[tuple[int, float, int]], u: int,
                     dist: int, rng: random.Random) -> None:
    for v in state.neighbours[u]:
        if state.label[v] == UNCLAIMED:
            heapq.heappush(heap, (dist, rng.random(), v))


def unclaimed(state: PartitionState) -> list[int]:
    """Free cells no region could reach (walled in by divided start cells)."""
    return [u for u, free in enumerate(state.free) if free and state.label[u] == UNCLAIMED]
