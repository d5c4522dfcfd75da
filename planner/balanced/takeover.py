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

from planner.balanced.machine import BalancedRobot, validate_replay
from planner.offline.lockstep import TakeoverResult, replanner, replay
from planner.offline.rebalance import DEFAULT_RECOVERY, Recovery
from planner.types import IntArray, Plan


def simulate_failures(plan: Plan, failures: Mapping[int, int], *,
                      detection_delay: int = 0,
                      recovery: Recovery = DEFAULT_RECOVERY) -> TakeoverResult:
    """Replay ``plan`` when robot ``r`` fails at time ``failures[r]`` (after that many moves);
    ``recovery`` as in planner.offline.lockstep.simulate_failures.

    Raises UnsupportedPlanError for non-unit speeds, paths that are not 4-adjacent walks on
    the plan's cycle sub-cells, unknown robots, or negative times.
    """
    validate_replay(plan, failures, detection_delay)
    ids = [rp.robot for rp in plan.robots]
    cycle = plan.cycle
    on = cycle.index >= 0
    machines = [BalancedRobot(plan, robot, takeover=recovery == "takeover") for robot in ids]
    replayed = replay(machines, ids, [cycle.position(rp.path[0]) for rp in plan.robots],
                      failures, detection_delay, cycle.n, cycle.at, replanner(plan, recovery),
                      bodies=cycle if recovery == "rebalance" else None)

    def spread(values: IntArray, fill: int) -> IntArray:
        out = np.full(cycle.index.shape, fill, dtype=np.int64)
        out[on] = values[cycle.index[on]]
        return out

    return replayed.result(spread)
