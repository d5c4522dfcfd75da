"""Moving the seeds of squeezed robots a few cells away from crowded starts.

Robots that start side by side get one-cell-wide strip regions from the weighted Voronoi
step: a strip can pass no single cell on, so the transfer chains stall and a neighbour stays
far above the average (issue 7, 80 obstacles, k = 20-30). Such a robot need not cover a region
holding its start: it can walk a few moves to a seed cell with room around it and cover a
region grown from there, its load counting the walk (the same mechanism as the walk-out of
boxed-in robots). The seed is a farthest-point choice: among the cells within ``radius``
steps of the start, the one farthest (geodesically) from every other robot's seed, nearest
to the start on ties. The walk costs about 2 * radius moves of one robot, which the balancing
spreads over all k robots, so it is nearly free when it unblocks the chains.
"""

from __future__ import annotations

import functools
from collections import deque
from collections.abc import Iterable, Sequence

import numpy as np

from planner.balanced.state import PartitionState, articulation_points
from planner.geometry import cell_of, sub_cells_of
from planner.grid import WorkArea
from planner.types import SubCell

SQUEEZED = 8  # sub-cells (two cells) below the average before a seed is moved


def squeezed(state: PartitionState) -> list[int]:
    """Robots whose load is at least SQUEEZED sub-cells below the average, smallest first."""
    average = -(-sum(state.load) // state.k)
    low = [r for r in range(state.k) if state.load[r] + SQUEEZED <= average]
    return sorted(low, key=lambda r: (state.load[r], r))


def relocation_routes(area: WorkArea, state: PartitionState, robots: Iterable[int],
                      radius: int, seeds: Sequence[SubCell] | None = None
                      ) -> dict[int, tuple[SubCell, ...]]:
    """Walks (start first) to farthest-point seed cells within ``radius`` cells, by robot.

    Seeds avoid start cells, cells already chosen and articulation cells of the whole area
    (a seed inside a corridor would box a neighbour in). Robots with no better cell in reach
    (none farther from the others than their start) are left out. ``seeds`` are where the
    robots' regions grow from now (default: their starts); walks start at the real starts.
    """
    area_cells = {u for u, free in enumerate(state.free) if free}
    avoid = articulation_points(area_cells, state.neighbours)
    now = {r: state.flat(cell_of(s))
           for r, s in enumerate(area.starts if seeds is None else seeds)}
    avoid |= set(now.values()) | {state.flat(cell_of(s)) for s in area.starts}
    routes: dict[int, tuple[SubCell, ...]] = {}
    for robot in robots:
        home = state.flat(cell_of(area.starts[robot]))
        others = [u for r, u in now.items() if r != robot]
        room = cell_distances(state, others, area_cells)
        near = cell_distances(state, [home], area_cells, limit=radius)
        best = max(near, key=lambda u: (u not in avoid, room.get(u, 0), -near[u], -u))
        if best in avoid or room.get(best, 0) <= room.get(home, 0):
            continue
        route = sub_cell_route(area, area.starts[robot], set(sub_cells_of(state.cell(best))))
        if route is None:
            continue
        routes[robot] = route
        now[robot] = best
        avoid.add(best)
    return routes


def cell_distances(state: PartitionState, sources: Sequence[int], cells: set[int],
                   limit: int | None = None) -> dict[int, int]:
    """Breadth-first cell distances from the nearest source over ``cells`` (up to ``limit``)."""
    dist = dict.fromkeys(sources, 0)
    queue = deque(sources)
    while queue:
        u = queue.popleft()
        if limit is not None and dist[u] >= limit:
            continue
        for v in state.neighbours[u]:
            if v in cells and v not in dist:
                dist[v] = dist[u] + 1
                queue.append(v)
    return dist


def sub_cell_route(area: WorkArea, start: SubCell, goal: set[SubCell]
                   ) -> tuple[SubCell, ...] | None:
    """A shortest 4-connected walk over the area's sub-cells from start into ``goal``.

    Breadth-first, neighbours north, east, south, west, stopping at the first goal sub-cell
    taken from the queue. The search runs on flat indices of the sub-cell grid framed by a
    blocked border (no bounds tests, no tuples; the framed grid is cached per area).
    """
    h, w = area.sub_cells.shape
    grid = _framed(area.sub_cells.tobytes(), h, w)
    width = w + 2
    origin = (start[0] + 1) * width + start[1] + 1
    goals = {(r + 1) * width + c + 1 for r, c in goal}
    steps = (-width, 1, width, -1)
    parent = {origin: origin}
    queue = deque([origin])
    while queue:
        at = queue.popleft()
        if at in goals:
            path = [at]
            while path[-1] != origin:
                path.append(parent[path[-1]])
            return tuple((u // width - 1, u % width - 1) for u in reversed(path))
        for step in steps:
            nxt = at + step
            if grid[nxt] and nxt not in parent:
                parent[nxt] = at
                queue.append(nxt)
    return None


@functools.lru_cache(maxsize=4)
def _framed(sub_cells: bytes, h: int, w: int) -> bytes:
    """The h x w free flags (bytes of a bool array) framed by a row and column of blocked
    sub-cells on every side, flattened row by row."""
    inner = np.frombuffer(sub_cells, dtype=bool).reshape(h, w)
    framed = np.zeros((h + 2, w + 2), dtype=np.uint8)
    framed[1:-1, 1:-1] = inner
    return framed.tobytes()
