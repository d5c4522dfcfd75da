"""The plan every agent computes for itself, and its digest.

Agents never exchange plans: each computes the same one from the same inputs (world, starts
in robot-id order, algorithm, tree kind, seed) and they compare sha256 digests of a
canonical byte form, so a robot started with a different map or option is caught before
anyone moves.
"""

from __future__ import annotations

import hashlib
from collections.abc import Sequence

import numpy as np

from planner.geometry import cell_of
from planner.grid import work_area
from planner.offline.machine import check_replayable
from planner.offline.plan import make_plan
from planner.trees import build_tree
from planner.types import OccupancyGrid, Plan, SubCell


def compute_plan(grid: OccupancyGrid, starts: Sequence[SubCell], algo: str, tree: str,
                 seed: int) -> Plan:
    """The offline plan for ``starts``; PlannerError for user mistakes (bad starts, algo)."""
    area = work_area(grid, starts)
    spanning = build_tree(area.cells, tree, seed=seed, starts=[cell_of(s) for s in starts])
    plan = make_plan(area, spanning, algo)
    check_replayable(plan)
    return plan


def plan_digest(plan: Plan) -> str:
    """sha256 (hex) of the plan's canonical form: algo, cycle, and every robot's walk."""
    h = hashlib.sha256()
    h.update(f"mstc-plan/1 {plan.algo} n={plan.n} k={plan.k}\n".encode())
    h.update(np.ascontiguousarray(plan.cycle.path, dtype="<i8").tobytes())
    for rp in plan.robots:
        legs = ",".join(f"{leg.direction.value}{leg.length}" for leg in rp.legs)
        h.update(f"\nrobot {rp.robot} start {rp.start} at {rp.start_index} legs {legs}\n"
                 .encode())
        h.update(np.asarray(rp.path, dtype="<i8").tobytes())
    return h.hexdigest()
