"""Turn allocations (cycle-index walks) into a Plan of sub-cell paths."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from planner.allocation import make_ring
from planner.allocation.ring import slot_speeds
from planner.errors import RobotPlacementError
from planner.types import Cycle, IntArray, Plan, RobotAllocation, RobotPlan, SpanningTree, SubCell


def walk_indices(n: int, allocation: RobotAllocation) -> IntArray:
    """Cycle indices the robot stands on, start first, one per move (legs expanded)."""
    steps = [np.full(leg.length, leg.direction.sign, dtype=np.int64) for leg in allocation.legs]
    moves = np.concatenate([np.zeros(1, dtype=np.int64), *steps])
    return np.asarray((allocation.start_index + np.cumsum(moves)) % n, dtype=np.int64)


def build_plan(algo: str, cycle: Cycle, starts: Sequence[SubCell],
               allocations: Sequence[RobotAllocation], *,
               speeds: Sequence[float] | None = None,
               tree: SpanningTree | None = None) -> Plan:
    """A Plan whose robot ``r`` walks ``allocations[r]``'s legs along ``cycle``.

    Each path starts at the robot's start and lists every sub-cell stood on, the way back of a
    backtrack included, so consecutive entries are 4-adjacent and len(path) - 1 == steps.
    """
    if len(allocations) != len(starts):
        raise RobotPlacementError(
            f"{len(allocations)} allocations for {len(starts)} robot starts")
    ring = make_ring(cycle.n, [a.start_index for a in allocations])
    speed_of = dict(zip(ring.order, slot_speeds(ring, speeds), strict=True))
    robots: list[RobotPlan] = []
    for robot, (start, allocation) in enumerate(zip(starts, allocations, strict=True)):
        if allocation.robot != robot:
            raise ValueError(f"allocation {robot} is for robot {allocation.robot}: "
                             "allocations must be in robot-id order")
        if cycle.position(start) != allocation.start_index:
            raise RobotPlacementError(
                f"robot {robot} starts at {tuple(start)}, cycle index {cycle.position(start)}, "
                f"but its allocation starts at cycle index {allocation.start_index}")
        path = cycle.path[walk_indices(cycle.n, allocation)]
        robots.append(RobotPlan(
            robot=robot, start=(int(start[0]), int(start[1])),
            start_index=allocation.start_index, legs=allocation.legs,
            path=tuple((int(r), int(c)) for r, c in path.tolist()),
            speed=speed_of[robot]))
    k = len(robots)
    bound = math.ceil(cycle.n / k) - 1 if k else 0
    notes = (f"{algo}: n = {cycle.n} sub-cells, k = {k} robots, "
             f"lower bound ceil(n/k) - 1 = {bound} moves",)
    return Plan(algo=algo, cycle=cycle, robots=tuple(robots), tree=tree, notes=notes)
