"""Robustness of balanced plans: a dead robot's region is finished by a live robot.

Pure discrete-time semantics in the style of planner.offline (paper 003, Alg. 2), for plans
whose robots walk their own regions rather than legs of one cycle: one BalancedRobot
(planner.balanced.machine, where the takeover rule is stated) per robot, driven by the
offline family's lockstep loop (planner.offline.lockstep.replay); a robot is known dead
``detection_delay`` steps after it failed.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np

from planner.balanced.machine import BalancedRobot
from planner.errors import UnsupportedPlanError
from planner.invariants import InvariantViolation, check_path_moves
from planner.offline.lockstep import TakeoverResult, replay
from planner.types import IntArray, Plan


def simulate_failures(plan: Plan, failures: Mapping[int, int], *,
                      detection_delay: int = 0) -> TakeoverResult:
    """Replay ``plan`` when robot ``r`` fails at time ``failures[r]`` (after that many moves).

    Raises UnsupportedPlanError for non-unit speeds, paths that are not 4-adjacent walks on
    the plan's cycle sub-cells, unknown robots, or negative times.
    """
    _validate(plan, failures, detection_delay)
    ids = [rp.robot for rp in plan.robots]
    cycle = plan.cycle
    on = cycle.index >= 0
    machines = [BalancedRobot(plan, robot) for robot in ids]
    replayed = replay(machines, ids, [cycle.position(rp.path[0]) for rp in plan.robots],
                      failures, detection_delay, cycle.n, cycle.at)

    def spread(values: IntArray, fill: int) -> IntArray:
        out = np.full(cycle.index.shape, fill, dtype=np.int64)
        out[on] = values[cycle.index[on]]
        return out

    return replayed.result(spread)


def _validate(plan: Plan, failures: Mapping[int, int], delay: int) -> None:
    ids = [rp.robot for rp in plan.robots]
    if not ids or len(set(ids)) != len(ids):
        raise UnsupportedPlanError(f"the plan's robot ids {ids} are empty or repeated")
    for robot, time in failures.items():
        if robot not in ids:
            raise UnsupportedPlanError(f"failure of robot {robot}: no such robot in the plan")
        if time < 0:
            raise UnsupportedPlanError(f"robot {robot} fails at time {time}; times are >= 0")
    if delay < 0:
        raise UnsupportedPlanError(f"detection delay {delay} is negative")
    on = plan.cycle.index >= 0
    for rp in plan.robots:
        if rp.speed != 1.0:
            raise UnsupportedPlanError(
                f"robot {rp.robot} has speed {rp.speed}: only unit-speed plans can be replayed")
        try:
            check_path_moves(rp.path)
        except InvariantViolation as exc:
            raise UnsupportedPlanError(f"robot {rp.robot}: {exc}") from exc
        if not all(on[r, c] for r, c in rp.path):
            raise UnsupportedPlanError(f"robot {rp.robot} walks off the plan's sub-cells")
