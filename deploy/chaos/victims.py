"""Which robots a death at a share of the coverage would find still at work.

A late death drawn at random found its robot idle, its own walk done, in 8 of 20 deaths of
campaign 6104 and 5 of 20 of 6105 (nb and bt plans are uneven, so short walks end early):
such a death tests little of the recovery. For an offline algorithm the plan is known
before the fleet starts (``mstc up`` makes the same one from the same seed), so the
campaign replays it in lockstep (every robot one move per step, as the plan counts its
makespan) to the step at which the ordered coverage is reached, and draws the victim among
the robots with uncovered sub-cells still ahead of them. The fleet does not move in lockstep
(each robot as fast as its process is scheduled), so this is a likely set, not a promise.
On-line algorithms plan nothing ahead: their victims stay drawn from every robot.
"""

from __future__ import annotations

from collections.abc import Sequence

from deploy.errors import UsageError
from deploy.kill_orders import covered_for
from deploy.monitor.coverage import reachable_sub_cells
from deploy.settings import UpSettings, mission_starts, offline_plan
from planner.algorithms import Family, algorithm
from planner.errors import PlannerError
from planner.maps import resolve_world
from planner.types import SubCell


def busy_robots(paths: Sequence[Sequence[SubCell]], count: int) -> tuple[int, ...]:
    """Robots (indices of ``paths``) with a sub-cell nobody has covered yet still ahead on
    their path at the first lockstep step by which ``count`` distinct sub-cells are covered
    (start sub-cells at step 0); () if the paths never cover that many."""
    covered: set[SubCell] = set()
    longest = max((len(path) for path in paths), default=0)
    for step in range(longest):
        covered.update(path[step] for path in paths if step < len(path))
        if len(covered) >= count:
            return tuple(robot for robot, path in enumerate(paths)
                         if any(sub not in covered for sub in path[step + 1:]))
    return ()


def busy_at(world: str, algo: str, robots: int, seed: int, percent: float) -> tuple[int, ...]:
    """The robots of ``mstc up -n robots --world world --algo algo --seed seed`` with work
    left when ``percent`` of the reachable sub-cells are covered, by the plan's lockstep
    replay; () for an on-line algorithm or a mission ``mstc up`` would refuse."""
    if algorithm(algo).family is Family.ONLINE:
        return ()
    settings = UpSettings(robots=robots, world=world, algo=algo, seed=seed)
    try:
        grid = resolve_world(world)
        starts = mission_starts(settings, grid)
        plan = offline_plan(settings, grid, starts)
    except (PlannerError, UsageError):
        # `mstc up` refuses the same mission with the same message, and the trial records
        # it: not this module's to report
        return ()
    total = int(reachable_sub_cells(grid, starts).sum())
    return busy_robots([robot.path for robot in plan.robots], covered_for(percent, total))
