"""Lockstep coverage with injected robot failures: robot r is lost at step t.

"Lost at step t" is what a fleet sees when a robot's report of step t never comes: the team
decided step t's moves with the robot, the robot did not arrive (it died between its report of
step t - 1 and its report of t), so a node only it was entering stays unvisited, and it is
removed at step t's boundary; step t + 1 then repairs the trail. The driver runs the team
replica that every fleet agent runs (planner.treecover.team), so a fleet mission whose agents
removed robot r at step t takes exactly the steps of ``run_with_failures(..., {r: t})``.

Lemma 4.1 is checked after every step. At a step where a robot is lost it may fail: the lost
robot may have been walking to the only node joining two parts of the team, and nobody can
know before it fails to arrive. Such *death steps* are counted apart (``cut_at_death``);
every other step must be connected, the repair step included.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from planner.errors import PlannerError
from planner.treecover.team import TeamReplica
from planner.treecover.types import Algo, CoverageResult, Splits, Tree


@dataclass(frozen=True, eq=False)
class FailureRun:
    """``result.connected``: every step that is not a death step was connected;
    ``cut_at_death``: death steps at which the survivors were not; ``replans``: (step,
    splits) of every re-plan of the survivors."""

    result: CoverageResult
    cut_at_death: int
    replans: tuple[tuple[int, Splits], ...]


def run_with_failures(tree: Tree, robots: int, algo: Algo | str, failures: Mapping[int, int],
                      splits: Splits | None = None) -> FailureRun:
    """Cover ``tree`` like ``run_coverage`` while robot r is lost at step ``failures[r]`` (a
    loss after the run has ended changes nothing). ``robots`` counts the initial team."""
    if robots < 1:
        raise PlannerError(f"need at least one robot (got {robots})")
    bad = sorted(r for r, s in failures.items() if not 0 <= r < robots or s < 0)
    if bad:
        raise PlannerError(f"failures name robots 0..{robots - 1} and steps >= 0 (got {bad})")
    if len(failures) >= robots:
        raise PlannerError(f"at least one of the {robots} robots must survive")
    replica = TeamReplica(tree, robots, algo, splits)
    first_splits = replica.splits
    by_step: dict[int, list[int]] = {}
    for robot, step in failures.items():
        by_step.setdefault(step, []).append(robot)
    connected, cut_at_death = True, 0
    explore_time = 0
    occupied: list[int] = []
    state = replica.state
    while True:
        lost = by_step.get(replica.step, [])
        replica.remove(lost)
        if replica.step > 0:
            if lost:
                cut_at_death += not state.connected()
            else:
                connected = connected and state.connected()
            occupied.append(len(state.at))
        if state.remaining == 0 and not explore_time:
            explore_time = replica.step
        if replica.done():
            break
        replica.advance()
    result = CoverageResult(replica.algo, robots, first_splits, state.time, explore_time,
                            2 * (tree.n - 1), connected, np.array(state.visit_time),
                            tuple(occupied))
    return FailureRun(result, cut_at_death, tuple(replica.replans))
