"""The plan every agent computes for itself, and its digest (planner.digest).

Agents never exchange plans: each computes the same one from the same inputs (world, starts
in robot-id order, algorithm, tree kind, seed) and they compare sha256 digests of a
canonical byte form, so a robot started with a different map or option is caught before
anyone moves.
"""

from __future__ import annotations

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


def robot_machine(plan: Plan, algo: str, robot: int, *, takeover: bool = True) -> PlanRobot:
    """Robot ``robot``'s state machine for ``plan``: the one the registry names for ``algo``
    (the lockstep replay drives the same class); ``takeover`` False when a re-plan, not the
    machine, recovers from deaths."""
    machine: PlanRobot = algorithm(algo).load_machine()(plan, robot, takeover=takeover)
    return machine
