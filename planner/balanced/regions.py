"""Partition of the work-area into one connected region per robot, of near-equal size.

Seed (shared start cells divided, seeds.py), weighted Voronoi (voronoi.py), grow
smallest-first (growth.py), then balance (balance.py). Sizes are in sub-cells; with whole
cells and half-cell leaves the largest region reaches 2 * ceil(n / 2k) sub-cells whenever the
map's shape allows. A robot boxed in by other robots' start cells (a dead end sealed by a
neighbour's start) can be sent out first: ``escape_routes`` finds its way to the nearest
cell it could own, and a second partition seeds it there, its load counting the walk out.
Robots squeezed into strips by neighbours that start beside them are moved the same way to
roomier seeds a few cells off (relocate.py), greedily, while that lowers the largest load.
If the largest load is still above the average, regions grown from well-spread seeds are
tried too, every robot walking to the region an assignment gives it (assign.py). If that
still stalls, robots at or below the average are sent to the most loaded regions
(reinforce.py). Last, walking robots are seeded a cell earlier along their walks
(pullback.py), if that is better.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Iterator, Sequence

from planner.balanced.assign import MakePartition, assigned_partition, reassigned
from planner.balanced.balance import balance
from planner.balanced.growth import grow, seed_regions, unclaimed
from planner.balanced.pullback import pulled_back_routes
from planner.balanced.reinforce import reinforced, score
from planner.balanced.relocate import relocation_routes, squeezed, sub_cell_route
from planner.balanced.state import PartitionState, articulation_points
from planner.balanced.types import Partition
from planner.balanced.voronoi import adopt, voronoi_labels
from planner.geometry import cell_of, sub_cells_of
from planner.grid import WorkArea
from planner.types import SubCell

BOXED_SHORTFALL = 8  # sub-cells (two cells) below the best size before a robot is sent out
RELOCATION_RADII = (5, 8, 3)  # cells a squeezed robot may walk to a new seed, in turn
MAX_PARTITIONS = 4  # partitions per plan at most (each 0.03-0.15 s of CPU at k = 30)
# Robot-partitions the relocation tries may spend: a partition costs about k times more
# on large maps, and on the city maps of docs/balanced.md ("Planning at scale") relocation
# never won from k = 75 up, so k <= 50 keeps all three tries, k = 75 two, k = 100 one,
# k > 150 none.
RELOCATION_BUDGET = 150
# A largest load this close above the ideal ends the search for better partitions (at most
# one move in 200 of the makespan). On 40 x 40 maps (loads under 200 sub-cells) it is 0;
# on large maps with few robots each further partition is a pass over regions of hundreds
# of cells: obstacles:80x80:30%:1 at k = 20 made its first partition 4 sub-cells above the
# ideal (896) in 1.2 s of CPU, then 25 more, none better, 26 s in all.
NEAR_FRACTION = 1 / 200


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

    When balancing stalls, robots are sent out and the area partitioned again with them
    seeded elsewhere, their loads counting the walk: squeezed robots moved to roomier seeds
    a few cells away (relocate.py, one radius per try), or boxed-in robots walked out to the
    nearest open cell (escape_routes). A new partition is kept only if its largest load
    (walk included) is smaller, and later tries start from the best so far; at most
    MAX_PARTITIONS partitions are made so (fewer with many robots: RELOCATION_BUDGET). If
    the best is still above the average, robots are assigned to regions grown from spread
    seeds (assign.py, up to 1 + ASSIGN_ROUNDS more partitions), kept on the same terms. If
    the best is still above the average, robots are sent to the most loaded regions
    (reinforce.py, up to its MAX_PARTITIONS partitions). If it is still above the average
    and some robots walk, one more partition seeds them a cell earlier along their walks
    (pullback.py), kept on the same terms.
    """
    state = _partition_state(area, seed, None, None)
    if state is None:
        return _elsewhere(area, seed)
    goal = _goal(sum(state.load), state.k)
    best = state
    best_routes: dict[int, tuple[SubCell, ...]] = {}
    made = 1
    tried: set[frozenset[tuple[int, SubCell]]] = set()
    tries = min(MAX_PARTITIONS - 1, RELOCATION_BUDGET // state.k)
    while made <= tries and max(best.load) > goal:
        for routes in _route_sets(area, best, best_routes):
            key = frozenset((r, w[-1]) for r, w in routes.items())
            if key not in tried:
                break
        else:
            break
        tried.add(key)
        made += 1
        starts = [routes[r][-1] if r in routes else s for r, s in enumerate(area.starts)]
        offsets = [len(routes[r]) - 1 if r in routes else 0 for r in range(state.k)]
        again = _partition_state(area, seed, starts, offsets)
        if again is not None and max(again.load) < max(best.load):
            best, best_routes = again, routes
    def make(starts: Sequence[SubCell], offsets: Sequence[int] | None
             ) -> PartitionState | None:
        return _partition_state(area, seed, starts, offsets)

    if max(best.load) > goal:
        assigned = assigned_partition(area, make, goal, max(best.load))
        if assigned is not None and max(assigned[0].load) < max(best.load):
            best, best_routes = assigned
    if max(best.load) > goal:
        best, best_routes = _reinforced(area, make, goal, best, best_routes)
    if max(best.load) > goal and best_routes:
        best, best_routes = _pulled_back(area, seed, best, best_routes)
    return best.to_partition(best.transfers), best_routes


def _reinforced(area: WorkArea, make: MakePartition, goal: int, state: PartitionState,
                routes: dict[int, tuple[SubCell, ...]]
                ) -> tuple[PartitionState, dict[int, tuple[SubCell, ...]]]:
    """Robots sent to the most loaded regions (reinforce.py); then, with fewer than
    assign.STOP_ROUNDS_FROM robots, the robots assigned again to the regions that made
    (assign.reassigned: the walks in change with the regions), reinforced once more if
    that was a step forward (reinforce.score). Kept only if the largest load is lower than
    ``state``'s: walks are taken only when they pay."""
    best = reinforced(area, state, routes, goal, make)
    if max(best[0].load) > goal:
        again = reassigned(area, make, goal, best[0])
        if again is not None and score(again[0]) < score(best[0]):
            best = reinforced(area, again[0], again[1], goal, make)
    return best if max(best[0].load) < max(state.load) else (state, routes)


def _elsewhere(area: WorkArea, seed: int
               ) -> tuple[Partition | None, dict[int, tuple[SubCell, ...]]]:
    """Regions grown from seeds away from the starts (assign.py, then the pull-back), for
    when robots sharing start cells wall part of the map off from the regions grown round
    the starts; (None, {}) if those cannot be made either."""
    goal = _goal(area.n, len(area.starts))
    assigned = assigned_partition(
        area, lambda starts, offsets: _partition_state(area, seed, starts, offsets), goal)
    if assigned is None:
        return None, {}
    best, routes = assigned
    if max(best.load) > goal and routes:
        best, routes = _pulled_back(area, seed, best, routes)
    return best.to_partition(best.transfers), routes


def _pulled_back(area: WorkArea, seed: int, state: PartitionState,
                 routes: dict[int, tuple[SubCell, ...]]
                 ) -> tuple[PartitionState, dict[int, tuple[SubCell, ...]]]:
    """The partition with the walking robots seeded a cell earlier (pullback.py), if better."""
    shorter = pulled_back_routes(state, routes)
    saved = sum(len(w) - 1 for w in routes.values()) - sum(len(w) - 1 for w in shorter.values())
    # Skip partitions (0.02-0.07 s each) that cannot win, since none beats its average load,
    # or that barely move the seeds (on the instances, savings under k / 4 moves
    # never won: the regions come out as before).
    if 4 * saved < state.k or -(-(sum(state.load) - saved) // state.k) >= max(state.load):
        return state, routes
    starts = [shorter[r][-1] if r in shorter else s for r, s in enumerate(area.starts)]
    offsets = [len(shorter[r]) - 1 if r in shorter else 0 for r in range(state.k)]
    again = _partition_state(area, seed, starts, offsets)
    if again is not None and max(again.load) < max(state.load):
        return again, shorter
    return state, routes


def _ideal(total: int, k: int) -> int:
    """The average load rounded up to an even number of sub-cells: balancing stops there."""
    ideal = -(-total // k)
    return ideal + ideal % 2


def _goal(total: int, k: int) -> int:
    """The largest load from which no further partition is tried: the ideal, and on large
    regions NEAR_FRACTION of it more (nothing more below 1 / NEAR_FRACTION sub-cells)."""
    ideal = _ideal(total, k)
    return ideal + int(ideal * NEAR_FRACTION)


def _route_sets(area: WorkArea, state: PartitionState, routes: dict[int, tuple[SubCell, ...]]
                ) -> Iterator[dict[int, tuple[SubCell, ...]]]:
    """Candidate walk sets: boxed-in robots out, squeezed ones moved (one radius per set).

    A boxed-in robot (its region touches only others' pinned cells) walks to the nearest
    open cell (escape_routes); the other squeezed robots go to roomier seeds (relocate.py).
    """
    boxed = [r for r in _boxed(state) if r not in routes]
    base = {**routes, **escape_routes(area, state, boxed)} if boxed else dict(routes)
    robots = [r for r in squeezed(state) if r not in base]
    seeds = [base[r][-1] if r in base else s for r, s in enumerate(area.starts)]
    for radius in RELOCATION_RADII:
        found = relocation_routes(area, state, robots, radius, seeds) if robots else {}
        if found or len(base) > len(routes):
            yield {**base, **found}


def _boxed(state: PartitionState) -> list[int]:
    """Robots whose region touches no cell it could ever take (only others' pinned cells)."""
    out = []
    for robot in range(state.k):
        own = state.whole[robot] or {state.flat(cell_of(state.starts[robot]))}
        around = {v for u in own for v in state.neighbours[u] if v not in own}
        if around and all(state.pinned(v) or state.label[v] < 0 for v in around):
            out.append(robot)
    return out


def escape_routes(area: WorkArea, state: PartitionState, robots: Sequence[int] | None = None
                  ) -> dict[int, tuple[SubCell, ...]]:
    """Walks (start first) that take stuck robots out to a cell they could own, by robot.

    A robot is stuck when its region, after balancing, is still at least BOXED_SHORTFALL
    sub-cells below the average: typically it starts in a dead end sealed by a neighbour's
    start cell. Its target is the nearest cell that is no start cell and no articulation
    cell of the whole area (one inside a corridor would box the neighbour in instead).
    ``robots`` limits the walks to those robots (when stuck).
    """
    best = -(-sum(state.load) // state.k)
    stuck = [r for r in range(state.k) if state.load[r] + BOXED_SHORTFALL <= best
             and (robots is None or r in robots)]
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
        route = sub_cell_route(area, area.starts[robot], set(sub_cells_of(state.cell(target))))
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
