"""Partition of the work-area into one connected region per robot, of near-equal size.

Seed (shared start cells divided, seeds.py), weighted Voronoi (voronoi.py), grow
smallest-first (growth.py), then balance (balance.py). Sizes are in sub-cells; with whole
cells and half-cell leaves the largest region reaches 2 * ceil(n / 2k) sub-cells whenever the
map's shape allows. A robot boxed in by other robots' start cells (a dead end sealed by a
neighbour's start) can be sent out first: ``escape_routes`` finds its way to the nearest
cell it could own, and a second partition seeds it there, its load counting the walk out.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence

from planner.balanced.balance import balance
from planner.balanced.growth import grow, seed_regions, unclaimed
from planner.balanced.state import PartitionState, articulation_points
from planner.balanced.types import Partition
from planner.balanced.voronoi import adopt, voronoi_labels
from planner.grid import WorkArea, cell_of, sub_cells_of
from planner.types import SubCell

BOXED_SHORTFALL = 8  # sub-cells (two cells) below the best size before a robot is sent out


def partition(area: WorkArea, *, seed: int = 0, starts: Sequence[SubCell] | None = None,
              offsets: Sequence[int] | None = None) -> Partition | None:
    """Balanced connected regions, one per robot holding its start (seeded tie-breaks).

    ``starts`` replaces the area's starts (where robots begin their regions) and ``offsets``
    adds moves per robot. None when some cells cannot join any region: only possible when
    cells where several robots start wall off part of the map from every region that grows.
    """
    state = _partition_state(area, seed, starts, offsets)
    return None if state is None else state.to_partition(state.transfers)


def _partition_state(area: WorkArea, seed: int, starts: Sequence[SubCell] | None,
                     offsets: Sequence[int] | None) -> PartitionState | None:
    state = PartitionState(area.cells, area.starts if starts is None else starts, offsets)
    seed_regions(state)
    adopt(state, voronoi_labels(state))
    grow(state, seed)
    if unclaimed(state):
        return None
    state.transfers = balance(state, max_chains=4 * area.cell_count + 16)
    return state


def plan_regions(area: WorkArea, *, seed: int = 0
                 ) -> tuple[Partition | None, dict[int, tuple[SubCell, ...]]]:
    """The partition to plan with, and the walks out for robots that start outside theirs.

    Stuck robots (see escape_routes) are sent out and the area partitioned again with them
    seeded at their targets; the second partition is kept only if its largest load (walk
    out included) is smaller.
    """
    state = _partition_state(area, seed, None, None)
    if state is None:
        return None, {}
    routes = escape_routes(area, state)
    if routes:
        starts = [routes[r][-1] if r in routes else s for r, s in enumerate(area.starts)]
        offsets = [len(routes[r]) - 1 if r in routes else 0 for r in range(state.k)]
        again = _partition_state(area, seed, starts, offsets)
        if again is not None and max(again.load) < max(state.load):
            return again.to_partition(again.transfers), routes
    return state.to_partition(state.transfers), {}


def escape_routes(area: WorkArea, state: PartitionState) -> dict[int, tuple[SubCell, ...]]:
    """Walks (start first) that take stuck robots out to a cell they could own, by robot.

    A robot is stuck when its region, after balancing, is still at least BOXED_SHORTFALL
    sub-cells below the average: typically it starts in a dead end sealed by a neighbour's
    start cell. Its target is the nearest cell that is no start cell and no articulation
    cell of the whole area (one inside a corridor would box the neighbour in instead).
    """
    best = -(-sum(state.load) // state.k)
    stuck = [r for r in range(state.k) if state.load[r] + BOXED_SHORTFALL <= best]
    if not stuck:
        return {}
    area_cells = {u for u, free in enumerate(state.free) if free}
    avoid = articulation_points(area_cells, state.neighbours)
    avoid |= {state.flat(cell_of(s)) for s in area.starts}
    routes: dict[int, tuple[SubCell, ...]] = {}
    for robot in stuck:
        target = _nearest_open_cell(state, robot, avoid)
        if target is None:
            continue
        route = _sub_cell_route(area, area.starts[robot], set(sub_cells_of(state.cell(target))))
        if route is not None:
            routes[robot] = route
            avoid.add(target)
    return routes


def _nearest_open_cell(state: PartitionState, robot: int, avoid: set[int]) -> int | None:
    """Nearest cell (breadth-first over free cells) of another region, not in ``avoid``."""
    sources = list(state.whole[robot]) or [state.flat(cell_of(state.starts[robot]))]
    seen = set(sources)
    queue = deque(sources)
    while queue:
        u = queue.popleft()
        if state.label[u] >= 0 and state.label[u] != robot and u not in avoid:
            return u
        for v in state.neighbours[u]:
            if v not in seen:
                seen.add(v)
                queue.append(v)
    return None


def _sub_cell_route(area: WorkArea, start: SubCell, goal: set[SubCell]
                    ) -> tuple[SubCell, ...] | None:
    """A shortest 4-connected walk over the area's sub-cells from start into ``goal``."""
    free = area.sub_cells
    h, w = free.shape
    parent: dict[SubCell, SubCell] = {start: start}
    queue = deque([start])
    while queue:
        at = queue.popleft()
        if at in goal:
            path = [at]
            while path[-1] != start:
                path.append(parent[path[-1]])
            return tuple(path[::-1])
        r, c = at
        for nxt in ((r - 1, c), (r, c + 1), (r + 1, c), (r, c - 1)):
            if 0 <= nxt[0] < h and 0 <= nxt[1] < w and free[nxt] and nxt not in parent:
                parent[nxt] = at
                queue.append(nxt)
    return None

