"""The digest of a plan: what agents compare before anyone moves, and what a record keeps.

A sha256 of a canonical byte form of the plan (algo, cycle, every robot's start and walk).
Here, beside the planner, because both sides need it: the agents (agent/offline/plan.py)
compare it across the fleet, and the monitor (deploy/monitor/walkouts.py) checks that a plan
made again from a record is the one the robots announced; the monitor imports nothing from
the agents.
"""

from __future__ import annotations

import hashlib

import numpy as np

from planner.types import Plan


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
