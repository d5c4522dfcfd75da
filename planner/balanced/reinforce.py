"""One more robot for the most loaded region, where the balancing has stalled.

Rooms behind one-cell doors make dead-end chains: a row of rooms whose only way out is
through the next one. Every robot covering part of such a chain walks in through the door
cells, which one region each can hold, so the chain's work and walks are shared by the
robots the assignment (assign.py) happened to send there, however the regions inside it
are drawn: four robots on four rooms of 624 sub-cells with 165 moves of walking end at
about 197 moves each, where the map's average is 179 (rooms 40 x 40, seed 81, k = 30).
No transfer chain fixes that; a fifth robot does. So, while the largest load is above the
average: the cell of the most loaded region farthest from where its robot enters it (no
start cell, no articulation cell of the area) is taken as a new seed for one of the
MOVERS robots at or below the average load nearest to it, which walks there; the area is
partitioned again (every region regrown, the walk in that robot's load) and the first
move that lowers the largest load (or the number of regions at it) is kept.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from planner.balanced.assign import UNREACHABLE
from planner.balanced.relocate import cell_distances, sub_cell_route
from planner.balanced.state import PartitionState, articulation_points
from planner.geometry import cell_of, sub_cells_of
from planner.grid import WorkArea
from planner.types import SubCell

Routes = dict[int, tuple[SubCell, ...]]
MakePartition = Callable[[Sequence[SubCell], Sequence[int] | None], PartitionState | None]

MOVERS = 3  # robots tried for each new seed, nearest first
MAX_PARTITIONS = 12  # partitions made here at most (0.05-0.15 s each at k = 30)
# Robot-partitions to spend (a partition costs about k times more on large maps): all 12
# up to k = 30, 3 at k = 100, 1 at k = 300.
BUDGET = 360


def reinforced(area: WorkArea, state: PartitionState, routes: Routes, goal: int,
               make: MakePartition) -> tuple[PartitionState, Routes]:
    """``state`` and its walks (``routes``, start first, by robot), or a partition with a
    lower largest load, or as low and held by fewer regions (a step on the way, which the
    caller may not keep: regions.py takes walks only when they lower the largest load),
    after robots were sent to the most loaded regions. ``make(starts, offsets)``
    partitions the area from those seeds with those walks in the loads; ``goal`` is the
    average load, where it stops."""
    k = state.k
    budget = min(MAX_PARTITIONS, BUDGET // k)
    cells = {u for u, free in enumerate(state.free) if free}
    avoid = articulation_points(cells, state.neighbours)
    avoid |= {state.flat(cell_of(s)) for s in area.starts}
    best, best_routes = state, dict(routes)
    tried: set[tuple[int, int]] = set()
    made = 0
    while made < budget and max(best.load) > goal:
        target = _new_seed(best, best_routes, area, avoid)
        if target is None:
            break
        near = cell_distances(best, [target], cells)
        average = sum(best.load) / k
        movers = sorted((r for r in range(k) if best.load[r] <= average
                         and (r, target) not in tried),
                        key=lambda r: (near.get(best.flat(cell_of(area.starts[r])), UNREACHABLE),
                                       r))[:MOVERS]
        found = None
        for robot in movers:
            tried.add((robot, target))
            route = sub_cell_route(area, area.starts[robot],
                                   set(sub_cells_of(best.cell(target))))
            if route is None:
                continue
            trial = {**best_routes, robot: route}
            made += 1
            again = make([trial[r][-1] if r in trial else s for r, s in enumerate(area.starts)],
                         [len(trial[r]) - 1 if r in trial else 0 for r in range(k)])
            if again is not None and score(again) < score(best):
                found = (again, trial)
                break
            if made >= budget:
                break
        if found is None:
            break
        best, best_routes = found
    return best, best_routes


def _new_seed(state: PartitionState, routes: Routes, area: WorkArea,
              avoid: set[int]) -> int | None:
    """The cell of the most loaded region (lowest robot on ties) farthest, through the
    region, from where its robot enters it; None if every cell is to be avoided."""
    top = max(range(state.k), key=lambda r: (state.load[r], -r))
    entry = state.flat(cell_of(routes[top][-1] if top in routes else area.starts[top]))
    region = state.whole[top]
    if entry not in region:
        return None  # a region of leaves only: nothing to share
    far = cell_distances(state, [entry], region)
    spots = [u for u in far if u not in avoid]
    return max(spots, key=lambda u: (far[u], -u)) if spots else None


def score(state: PartitionState) -> tuple[int, int]:
    """The largest load, then how many regions hold it (fewer: a step towards lowering it)."""
    top = max(state.load)
    return top, state.load.count(top)
