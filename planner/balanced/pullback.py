"""Pulling walking robots' seeds back along their walks: less walking, the same regions.

A robot that walks to its region (relocate.py, assign.py) is seeded where its walk enters
the region, and its load counts the walk. After balancing, the region around that seed
has moved: the walk may already cross the region earlier, and the cell it crosses just
before entering belongs to a neighbour that could spare it. Seeding the robot there instead
covers that cell rather than walking through it, so the total walk, and with it the sum of
the loads, shrinks (about 2 moves a cell); partitioning the area again from the pulled-back
seeds lets the balancing spread the saving (issue 7, 80 obstacles, k = 30 seed 5: the
average load with the walks was already the lower bound + 4).
"""

from __future__ import annotations

from planner.balanced.state import PartitionState
from planner.geometry import cell_of
from planner.types import SubCell

Routes = dict[int, tuple[SubCell, ...]]


def pulled_back_routes(state: PartitionState, routes: Routes) -> Routes:
    """The walks cut one cell earlier, by robot (a robot left out walks no more).

    Each walk is cut at its first sub-cell in its robot's region (whole cells), and one
    cell earlier still when the cell crossed before that is a whole cell of another region
    that it could give (not pinned, not a cut cell of that region, not its last cell). The
    robot is then seeded at the walk's first sub-cell in the cell it stops at. No two
    robots stop in the same cell (a shared seed cell would have to be divided): the cell
    before is taken only if no other robot stops there, in robot order.
    """
    cells = {robot: [state.flat(cell_of(s)) for s in walk] for robot, walk in routes.items()}
    entry = {robot: next((i for i, u in enumerate(path) if u in state.whole[robot]),
                         len(path) - 1)
             for robot, path in cells.items()}
    taken = {path[entry[robot]] for robot, path in cells.items()}
    for robot in sorted(cells):
        path, i = cells[robot], entry[robot]
        if i > 0 and path[i - 1] not in taken and _spare(state, path[i - 1]):
            taken.add(path[i - 1])
            entry[robot] = path.index(path[i - 1])
    return {robot: routes[robot][: i + 1] for robot, i in entry.items() if i > 0}


def _spare(state: PartitionState, u: int) -> bool:
    """Whether ``u``'s region could give it up and stay connected with its pins."""
    owner = state.label[u]
    return (owner >= 0 and not state.pinned(u) and len(state.whole[owner]) > 1
            and u not in state.cut_cells(owner))
