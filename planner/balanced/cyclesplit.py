"""Split one STC cycle into stretches that any robot may take (issue 14, item 3; beyond the papers).

Every robot walks a shortest sub-cell path to one end of a stretch of the cycle and covers
the stretch from there, forwards or backwards; its cost is that walk plus the stretch's
length minus one. Unlike MSTC* (planner.tmstc.division, where the robots keep their order
along the cycle) any robot may take any stretch, so a robot can jump to a part of the cycle
that winds past it. This is what wins where balanced regions cannot be grown round the
starts (mazes: every cell a cut cell; a room behind a door): the registry's planner
(``plan.plan_for``) keeps it only when its makespan beats the regions and opt.

The search (a greedy over the robots' reaches, binary search on the bound) is
``planner.stretches``, shared with the re-plan after a death. The bound ``below`` (the best
plan known) skips first cuts that cannot beat it with one test.
"""

from __future__ import annotations

import numpy as np

from planner.balanced.assign import start_distances
from planner.balanced.relocate import sub_cell_route
from planner.grid import WorkArea
from planner.stretches import Reach, Stretch
from planner.types import Cycle, RobotPlan, SubCell

DEPTH = 2  # picks looked ahead past each of them, below MANY robots (1 from MANY)
FIRST_CUTS = 8  # first cuts tried, evenly round the cycle
FIRST_CUTS_MANY = 2  # from MANY robots, where one greedy costs k reach scans of k robots
MANY = 50


def give_idle_robots_their_starts(stretches: list[Stretch], positions: list[int],
                                  n: int) -> list[Stretch]:
    """Every robot a stretch, no cost grown. A robot left out takes the part of the stretch
    holding its start from its start on (in that stretch's direction; entered with no walk);
    where its start is the stretch's entry it takes the whole stretch, and the owner, who
    walked there, is left out in turn. Each such swap leaves one walking robot fewer, so it
    ends."""
    out = list(stretches)
    idle = sorted(set(range(len(positions))) - {s.robot for s in out})
    while idle:
        robot = idle.pop(0)
        at = positions[robot]
        i, s = next((i, s) for i, s in enumerate(out) if (at - s.first) % n < s.end - s.first)
        spot = s.first + (at - s.first) % n
        if spot == s.entry:
            out[i] = Stretch(robot, s.first, s.end, s.forward)
            idle.append(s.robot)
        elif s.forward:
            out[i] = Stretch(s.robot, s.first, spot, True)
            out.append(Stretch(robot, spot, s.end, True))
        else:
            out[i] = Stretch(s.robot, spot + 1, s.end, False)
            out.append(Stretch(robot, s.first, spot + 1, False))
    return out


def split_cycle(area: WorkArea, cycle: Cycle, *, below: int) -> tuple[RobotPlan, ...] | None:
    """Robot plans (walk, then stretch) of a split of ``cycle`` whose makespan is under
    ``below``, or None if the greedy finds none. ``cycle`` must run through the area's
    sub-cells."""
    k = len(area.starts)
    lower = -(-area.n // k) - 1
    if below <= lower:
        return None
    w = area.sub_cells.shape[1]
    flat = cycle.path[:, 0] * w + cycle.path[:, 1]
    walks = start_distances(area, limit=below)[:, flat]
    few = k < MANY
    reach = Reach(walks, depth=DEPTH if few else 1)
    cuts = FIRST_CUTS if few else FIRST_CUTS_MANY
    firsts = np.unique(np.linspace(0, cycle.n, cuts, endpoint=False).astype(np.int64))
    found = reach.best(lower, below, firsts)
    if found is None:
        return None
    positions = [cycle.position(s) for s in area.starts]
    stretches = give_idle_robots_their_starts(found[1], positions, cycle.n)
    plans: dict[int, RobotPlan] = {}
    for s in stretches:
        start = area.starts[s.robot]
        entry = cycle.at(s.entry)
        walk = sub_cell_route(area, start, {entry}) if entry != start else (start,)
        assert walk is not None  # the cycle is the area's: every sub-cell is reachable
        order = range(s.first, s.end) if s.forward else range(s.end - 1, s.first - 1, -1)
        stretch: list[SubCell] = [cycle.at(i) for i in order]
        plans[s.robot] = RobotPlan(robot=s.robot, start=start,
                                   start_index=positions[s.robot], legs=(),
                                   path=walk[:-1] + tuple(stretch), walk_out=len(walk) - 1)
    return tuple(plans[r] for r in range(k))
