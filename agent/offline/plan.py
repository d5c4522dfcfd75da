"""The plan every agent computes for itself, and its digest (planner.digest).

Each agent computes the same plan from the same inputs (world, starts in robot-id order,
algorithm, tree kind, seed) and they compare sha256 digests of a canonical byte form, so a
robot started with a different map or option is caught before anyone moves. In a crowd one
robot computes it for all and the others check it (agent.offline.planshare); the digests
are compared all the same.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

from planner.algorithms import algorithm
from planner.geometry import cell_of
from planner.grid import work_area
from planner.offline.machine import PlanRobot
from planner.trees import build_tree
from planner.types import OccupancyGrid, Plan, SubCell


def compute_plan(grid: OccupancyGrid, starts: Sequence[SubCell], algo: str, tree: str,
                 seed: int) -> Plan:
    """The offline plan for ``starts`` by the registry's planner of ``algo``; PlannerError
    for user mistakes (bad starts, algo) or a plan the algorithm's machine cannot run."""
    area = work_area(grid, starts)
    spanning = build_tree(area.cells, tree, seed=seed, starts=[cell_of(s) for s in starts])
    entry = algorithm(algo)
    plan: Plan = entry.load_plan()(area, spanning, algo, seed)
    entry.load_machine().check_replayable(plan)  # type: ignore[attr-defined]
    return plan


def fleet_plan(grid: OccupancyGrid, starts: Sequence[SubCell], participants: Sequence[int],
               algo: str, tree: str, seed: int) -> Plan:
    """compute_plan for the agreed participants (``starts`` theirs, in robot-id order), its
    robots carrying their fleet ids: a robot that took no part leaves a gap in the ids, not a
    section nobody walks. Module-level so that a process of its own can run it."""
    plan = compute_plan(grid, starts, algo, tree, seed)
    return dataclasses.replace(plan, robots=tuple(
        dataclasses.replace(rp, robot=participants[i]) for i, rp in enumerate(plan.robots)))


def robot_machine(plan: Plan, algo: str, robot: int, *, takeover: bool = True) -> PlanRobot:
    """Robot ``robot``'s state machine for ``plan``: the one the registry names for ``algo``
    (the lockstep replay drives the same class); ``takeover`` False when a re-plan, not the
    machine, recovers from deaths."""
    machine: PlanRobot = algorithm(algo).load_machine()(plan, robot, takeover=takeover)
    return machine
