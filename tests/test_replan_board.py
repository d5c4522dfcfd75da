"""The re-plan board of the offline agents (agent.offline.replan): who a re-plan waits for."""

from __future__ import annotations

import dataclasses

import numpy as np

from agent.offline.plan import compute_plan
from agent.offline.replan import ReplanBoard
from bus import keys
from bus.drops import DropCounter
from bus.messages import ReplanReport, pack_covered
from planner.maps.worlds import builtin_world
from planner.types import Plan


def _plan_of(ids: tuple[int, ...]) -> Plan:
    """A plan of the builtin example whose robots carry fleet ids ``ids`` (gaps for robots
    that took no part), as the offline driver makes it."""
    starts = [(0, 0), (0, 2), (2, 0)][: len(ids)]
    plan = compute_plan(builtin_world("example"), starts, "opt", "dfs", 0)
    return dataclasses.replace(plan, robots=tuple(
        dataclasses.replace(rp, robot=ids[i]) for i, rp in enumerate(plan.robots)))


def _report(plan: Plan, robot: int, dead: tuple[int, ...]) -> ReplanReport:
    mine = next(rp for rp in plan.robots if rp.robot == robot)
    covered = np.zeros(plan.cycle.n, dtype=bool)
    return ReplanReport(robot, 1, dead, mine.start_index, (), pack_covered(covered), 0.0)


def _told(board: ReplanBoard, plan: Plan, robot: int, dead: tuple[int, ...]) -> None:
    assert board.on_report(keys.replan("m", robot), _report(plan, robot, dead))


def test_a_robot_that_took_no_part_is_no_member_of_any_re_plan() -> None:
    plan = _plan_of((0, 2, 3))  # robot 1 of 4 never announced its start
    board = ReplanBoard(plan, DropCounter())
    assert board.members == (0, 2, 3)
    # its death after planning is no epoch: nothing to re-plan
    assert board.epoch({1}) == ()
    assert board.epoch({1, 3}) == (3,)
    # a re-plan after robot 3's death waits for robots 0 and 2 only, never for robot 1
    assert board.missing((3,)) == [0, 2]
    _told(board, plan, 0, (3,))
    assert board.missing((3,)) == [2]
    _told(board, plan, 2, (3,))
    assert board.missing((3,)) == []
    inputs = board.inputs((3,))
    assert [s.robot for s in inputs.survivors] == [0, 2]
    # a report of a robot that took no part is refused, not kept
    foreign = ReplanReport(1, 1, (3,), 0, (), pack_covered(np.zeros(plan.cycle.n, dtype=bool)), 0.0)
    assert not board.on_report(keys.replan("m", 1), foreign)
    assert 1 not in board.reports and board.drops.total("replan", "invalid") == 1


def test_a_report_of_another_epoch_does_not_count() -> None:
    plan = _plan_of((0, 1, 2))
    board = ReplanBoard(plan, DropCounter())
    _told(board, plan, 0, (2,))
    _told(board, plan, 1, ())
    assert board.missing((2,)) == [1]
