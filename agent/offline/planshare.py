"""A crowded offline fleet's first plan, computed once: by its lowest participant, for all.

Every agent of a small fleet computes the plan from the agreed starts and the fleet compares
digests (agent.offline.plan). In a crowd that costs the fleet k times the plan's CPU at
once: 60 balanced agents on 2 cores (0.5-1.1 s of CPU each) planned for more than 25 s, and
robots starved meanwhile lost their liveliness tokens (declared dead before anyone moved).
From ``share_from`` participants on, the lowest participant (the *sharer*) computes the plan
in a process of its own (agent.offline.apart) and announces it (PlanShare); the others
check it and fly it: it was made from the inputs they hold (``plan_inputs``), it
rebuilds into a plan of that digest, every walk begins at its robot's agreed start and
moves one sub-cell at a time over the work-area, the walks cover it, the cycle is a closed
walk through all of it, and the robots' machine can run it. A share that fails a check, a
sharer known dead, or no share within ``share_wait`` makes the robot compute the plan itself:
the same plan, later (the digests are still compared before anyone moves). The trade-off,
as for a shared re-plan: a robot trusts the sharer's search (not that the plan is the best
one); the fleet's robots are authenticated and only robot r may put ``planned/<r>``
(docs/security.md).
"""

from __future__ import annotations

import dataclasses
import hashlib
from collections.abc import Sequence

import numpy as np

from agent.offline.apart import shared_by_one
from bus.messages import PlanShare, join_moves, pack_moves, split_moves, unpack_moves
from planner.algorithms import algorithm
from planner.digest import plan_digest
from planner.errors import PlannerError
from planner.grid import WorkArea
from planner.invariants import InvariantViolation, check_path_moves, check_plan
from planner.types import Cycle, Direction, Leg, OccupancyGrid, Plan, RobotPlan, SubCell

# Participants from which one computes the first plan for all: the crowd of
# agent.offline.driver.PULL_ROBOTS. Below, every agent computing it costs less than the
# sharer's process start-up (about a second) and the message.
SHARE_FROM = 26
# How long a robot waits for the shared plan before computing it itself: a safety net for a
# slow sharer, as for a shared re-plan (agent.offline.replan.share_wait).
SHARE_WAIT_MIN_S = 10.0
SHARE_WAIT_S_PER_ROBOT = 1.0
# ... and with the map, where a balanced plan grows fastest (rooms of 45 420 sub-cells:
# 7.6 s of CPU at k = 12, 40 s at k = 20): too short a wait only has every robot compute
# it after all, later; a sharer that dies is not waited for.
SHARE_WAIT_S_PER_SUB_CELL = 3e-3


class UnusableShareError(ValueError):
    """A shared plan that cannot be flown: the reason is the message."""


def share_wait(robots: int, sub_cells: int = 0) -> float:
    """Seconds a robot waits for the plan of a ``sub_cells`` work-area shared in a fleet of
    ``robots`` participants."""
    return max(SHARE_WAIT_MIN_S, SHARE_WAIT_S_PER_ROBOT * robots,
               SHARE_WAIT_S_PER_SUB_CELL * sub_cells)


def sharer(participants: Sequence[int], share_from: int, sub_cells: int = 0) -> int | None:
    """The participant that computes the plan of a ``sub_cells`` work-area for all, or None
    when each computes it (agent.offline.apart.shared_by_one: on a large map a balanced
    plan is 7.6-122 s of CPU at k = 12-25 on rooms of 45 420 sub-cells, and every
    participant computing it multiplied that)."""
    return (min(participants)
            if participants and shared_by_one(len(participants), sub_cells, share_from)
            else None)


def plan_inputs(grid: OccupancyGrid, participants: Sequence[int], starts: Sequence[SubCell],
                algo: str, tree: str, seed: int) -> str:
    """sha256 (hex) of everything a plan is made from: the map, the participants and their
    starts (in robot-id order), the algorithm, the tree kind and the seed."""
    h = hashlib.sha256()
    h.update(f"mstc-plan-inputs/1 {algo} {tree} {seed} {grid.free.shape}\n".encode())
    h.update(np.packbits(grid.free.astype(bool)).tobytes())
    h.update(repr([(r, tuple(s)) for r, s in zip(participants, starts, strict=True)]).encode())
    return h.hexdigest()


def share_of(plan: Plan, robot: int, incarnation: int, inputs: str) -> PlanShare:
    """``plan`` as robot ``robot`` shares it (its robots in robot-id order)."""
    path = plan.cycle.path
    return PlanShare(
        robot, incarnation, inputs, plan_digest(plan), (int(path[0][0]), int(path[0][1])),
        pack_moves(path), tuple(rp.steps for rp in plan.robots),
        join_moves([rp.path for rp in plan.robots]), tuple(rp.walk_out for rp in plan.robots),
        tuple(",".join(f"{leg.direction.value}{leg.length}" for leg in rp.legs)
              for rp in plan.robots),
        plan.notes, "")


def unshared(robot: int, incarnation: int, inputs: str, problem: str) -> PlanShare:
    """The share that tells the others to compute the plan themselves, and why."""
    return PlanShare(robot, incarnation, inputs, "", (0, 0), b"", (), b"", (), (), (), problem)


def plan_of(msg: PlanShare, area: WorkArea, participants: Sequence[int], algo: str) -> Plan:
    """The plan ``msg`` shares, rebuilt and checked for ``area`` (whose starts are the
    participants', in robot-id order); UnusableShareError naming the first problem."""
    k = len(participants)
    if msg.problem:
        raise UnusableShareError(f"not shared: {msg.problem}")
    if not (len(msg.lengths) == len(msg.walk_outs) == len(msg.legs) == k):
        raise UnusableShareError(f"walks of {len(msg.lengths)} robots, {k} participants")
    try:
        cycle = _cycle(msg, area)
        walks = split_moves(msg.moves, area.starts, msg.lengths)
        # numbered 0..k-1 as the work-area's starts are, for the check; fleet ids after it
        numbered = Plan(algo=algo, cycle=cycle, notes=msg.notes, robots=tuple(
            RobotPlan(robot=i, start=(int(start[0]), int(start[1])),
                      start_index=cycle.position(start), legs=_legs(msg.legs[i]),
                      path=tuple((int(r), int(c)) for r, c in walk), walk_out=msg.walk_outs[i])
            for i, (start, walk) in enumerate(zip(area.starts, walks, strict=True))))
        # robots revisit sub-cells on walk-outs and the papers' backtracking: coverage and
        # walks are what is checked here, the digest and the machine check the rest
        check_plan(numbered, area, max_visits=k + 1, own_revisits_only=False)
        plan = dataclasses.replace(numbered, robots=tuple(
            dataclasses.replace(rp, robot=participants[rp.robot]) for rp in numbered.robots))
    except (ValueError, InvariantViolation) as error:
        raise UnusableShareError(str(error)) from None
    if plan_digest(plan) != msg.digest:
        raise UnusableShareError(f"it rebuilds into plan {plan_digest(plan)[:12]}, not the "
                                 f"{msg.digest[:12]} it names")
    try:
        algorithm(algo).load_machine().check_replayable(plan)  # type: ignore[attr-defined]
    except PlannerError as error:
        raise UnusableShareError(str(error)) from None
    return plan


def _cycle(msg: PlanShare, area: WorkArea) -> Cycle:
    want = area.sub_cells
    n = int(want.sum())
    path = unpack_moves(msg.cycle, msg.cycle_start, n - 1)
    check_path_moves([(int(r), int(c)) for r, c in path[[-1, 0]]])  # it closes
    inside = (path >= 0).all(axis=1) & (path[:, 0] < want.shape[0]) & (path[:, 1] < want.shape[1])
    if not inside.all() or not want[path[:, 0], path[:, 1]].all():
        raise UnusableShareError("the cycle leaves the work-area")
    index = np.full(want.shape, -1, dtype=np.int64)
    index[path[:, 0], path[:, 1]] = np.arange(n)
    if int((index >= 0).sum()) != n:
        raise UnusableShareError("the cycle passes a sub-cell twice")
    return Cycle(path=path, index=index)


def _legs(text: str) -> tuple[Leg, ...]:
    legs = []
    for part in filter(None, text.split(",")):
        for direction in Direction:
            if part.startswith(direction.value) and part[len(direction.value):].isdigit():
                legs.append(Leg(direction, int(part[len(direction.value):])))
                break
        else:
            raise UnusableShareError(f"leg {part!r} is not a direction and a length")
    return tuple(legs)
