"""The offline robot's decisions as a sans-I/O state machine (Alg. 2 / Alg. 4 of paper 003).

A robot that finished its own walk watches its successor along the cycle and, once the
successor is known dead, walks counter-clockwise into the dead robot's region up to its last
uncovered sub-cell, then watches the dead robot's successor. The lockstep replay
(planner.offline.lockstep) drives one OfflineRobot per robot with perfect knowledge; the agent
process (agent/) drives its own from the bus and the body: the oracle and the fleet run the
same code. docs/trees-and-metrics.md states the rules in full.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from planner.errors import UnsupportedPlanError
from planner.types import BoolArray, Cycle, Plan, RobotPlan, SubCell


def region_of(rp: RobotPlan, n: int) -> tuple[int, int]:
    """(first cycle index, size) of the interval a robot's legs cover, CCW from its first."""
    offset = low = high = 0
    for leg in rp.legs:
        offset += leg.direction.sign * leg.length
        low, high = min(low, offset), max(high, offset)
    return ((rp.start_index + low) % n, high - low + 1)


def validate_replay(plan: Plan, failures: Mapping[int, int], delay: int) -> None:
    """Raise UnsupportedPlanError unless ``plan`` can be replayed with ``failures``."""
    ids = [rp.robot for rp in plan.robots]
    if not ids:
        raise UnsupportedPlanError("the plan has no robots")
    if len(set(ids)) != len(ids):
        raise UnsupportedPlanError(f"the plan repeats robot ids: {ids}")
    for robot, time in failures.items():
        if robot not in ids:
            raise UnsupportedPlanError(f"failure of robot {robot}: no such robot in the plan")
        if time < 0:
            raise UnsupportedPlanError(f"robot {robot} fails at time {time}; times are >= 0")
    if delay < 0:
        raise UnsupportedPlanError(f"detection delay {delay} is negative")
    n = plan.cycle.n
    for rp in plan.robots:
        if rp.speed != 1.0:
            raise UnsupportedPlanError(
                f"robot {rp.robot} has speed {rp.speed}: the takeover semantics count unit "
                "moves per time step, so only unit-speed plans can be replayed")
        _check_follows_legs(plan, rp)
    regions = sorted(region_of(rp, n) for rp in plan.robots)
    if sum(size for _, size in regions) != n or any(
            (first + size) % n != regions[(i + 1) % len(regions)][0]
            for i, (first, size) in enumerate(regions)):
        raise UnsupportedPlanError(
            f"the robots' regions {regions} (first index, size) do not tile the {n}-cycle")


def _check_follows_legs(plan: Plan, rp: RobotPlan) -> None:
    n = plan.cycle.n
    expected = [rp.start_index]
    for leg in rp.legs:
        base = expected[-1]
        expected.extend((base + leg.direction.sign * (j + 1)) % n for j in range(leg.length))
    got = [plan.cycle.position((int(r), int(c))) for r, c in rp.path]
    if got != expected:
        raise UnsupportedPlanError(
            f"robot {rp.robot}: its path does not follow its legs along the cycle")



@dataclass(frozen=True)
class MoveTo:
    """Step to the neighbouring sub-cell ``sub``, cycle index ``index``."""

    index: int
    sub: SubCell


@dataclass(frozen=True)
class WaitFor:
    """Nothing to do until robot ``watching`` is known dead or everything is covered."""

    watching: int


@dataclass(frozen=True)
class Finished:
    """The robot's walk is over and every sub-cell is known covered."""


RobotAction = MoveTo | WaitFor | Finished


@dataclass(frozen=True)
class TakeoverDecision:
    """The robot took over dead robot ``dead``: it walks CCW to cycle index ``target``
    (None when nothing of the dead robot's region was left uncovered)."""

    dead: int
    target: int | None


class PlanRobot(Protocol):
    """What a driver (the lockstep replay, the offline agent) asks of the state machine of
    an algorithm that walks a plan: OfflineRobot here, planner.balanced.machine.BalancedRobot.
    Places are cycle indices of ``cycle``; the registry (planner.algorithms) names the class
    for each algorithm, and its ``check_replayable(plan)`` says whether it can run a plan."""

    robot: int
    cycle: Cycle
    covered: BoolArray
    own_steps_left: int
    dead: set[int]
    position: int

    @property
    def all_covered(self) -> bool: ...

    @property
    def about_to_take_over(self) -> bool: ...

    @property
    def pending_route(self) -> tuple[int, ...]: ...

    def on_replan(self, route: tuple[int, ...]) -> None: ...

    @property
    def section_done(self) -> bool: ...

    def on_covered(self, index: int) -> None: ...

    def on_dead(self, robot: int) -> None: ...

    def on_moved(self) -> int: ...

    def next_action(self) -> RobotAction: ...

    def pop_decisions(self) -> list[TakeoverDecision]: ...


def check_replayable(plan: Plan) -> None:
    """Raise UnsupportedPlanError unless the takeover semantics can run ``plan``."""
    validate_replay(plan, {}, 0)


class RingRobot:
    """What every robot that walks a plan on a ring shares (OfflineRobot here,
    planner.balanced.machine.BalancedRobot): its walk, what it knows covered and dead, and
    the ring of successors it watches. Subclasses say how a takeover walks (``_decide``).

    Feed it what the robot learns — :meth:`on_covered` (anyone covered a cycle index),
    :meth:`on_dead` (a robot is known dead), :meth:`on_moved` (my last MoveTo is done) — and
    ask :meth:`next_action`. Every start is covered from the outset. Decisions are kept for
    :meth:`pop_decisions`.
    """

    def __init__(self, plan: Plan, robot: int, *, takeover: bool = True) -> None:
        by_id = {rp.robot: rp for rp in plan.robots}
        if robot not in by_id:
            raise UnsupportedPlanError(f"robot {robot} is not in the plan")
        cycle = self.cycle = plan.cycle
        self.robot = robot
        self.takeover = takeover  # False: a re-plan (on_replan), not this robot, recovers
        order = sorted(by_id, key=lambda r: by_id[r].start_index)
        self.successor = dict(zip(order, order[1:] + order[:1], strict=True))
        self.watching = self.successor[robot]
        mine = by_id[robot]
        self.position = cycle.position(mine.path[0])
        self._pending = deque(cycle.position(sub) for sub in mine.path[1:])
        self.own_steps_left = len(self._pending)
        self.covered = np.zeros(cycle.n, dtype=bool)
        self._uncovered = cycle.n
        self.dead: set[int] = set()
        self._decisions: list[TakeoverDecision] = []
        for rp in plan.robots:
            self.on_covered(cycle.position(rp.path[0]))

    @property
    def all_covered(self) -> bool:
        return self._uncovered == 0

    @property
    def about_to_take_over(self) -> bool:
        """True when the next :meth:`next_action` will decide a takeover (idle, coverage
        incomplete, the watched robot known dead): a driver may first refresh its knowledge."""
        return (self.takeover and not self._pending and not self.all_covered
                and self.watching != self.robot
                and self.watching in self.dead)

    @property
    def section_done(self) -> bool:
        """True once the robot has walked its own plan to the end."""
        return self.own_steps_left == 0

    def on_covered(self, index: int) -> None:
        """Some robot (this one included) stood on cycle index ``index``."""
        if not self.covered[index]:
            self.covered[index] = True
            self._uncovered -= 1

    def on_dead(self, robot: int) -> None:
        self.dead.add(robot)

    def on_moved(self) -> int:
        """The last MoveTo is done: the robot stands on (and covered) that index."""
        index = self._pending.popleft()
        self.position = index
        if self.own_steps_left > 0:
            self.own_steps_left -= 1
        self.on_covered(index)
        return index

    def next_action(self) -> RobotAction:
        """What to do now; decides takeovers when idle and coverage is incomplete."""
        if not self._pending and not self.all_covered:
            self._decide()
        if self._pending:
            index = self._pending[0]
            return MoveTo(index, self.cycle.at(index))
        if self.all_covered:
            return Finished()
        return WaitFor(self.watching)

    @property
    def pending_route(self) -> tuple[int, ...]:
        """The cycle indices this robot is still to walk, in order."""
        return tuple(self._pending)

    def on_replan(self, route: tuple[int, ...]) -> None:
        """A re-plan after a death (planner.offline.rebalance): walk ``route`` from here."""
        self._pending = deque(route)

    def pop_decisions(self) -> list[TakeoverDecision]:
        """Takeovers decided since the last call, in order."""
        out, self._decisions = self._decisions, []
        return out

    def _decide(self) -> None:
        raise NotImplementedError


class OfflineRobot(RingRobot):
    """One robot's offline MSTC life as a sans-I/O state machine (Alg. 2 / Alg. 4).

    The robot walks its own plan; then, while coverage is incomplete, it watches its
    successor along the cycle and, once that one is known dead, walks CCW to the last
    uncovered sub-cell of its region and watches the dead robot's successor (chained).
    """

    def __init__(self, plan: Plan, robot: int, *, takeover: bool = True) -> None:
        super().__init__(plan, robot, takeover=takeover)
        self.regions = {rp.robot: region_of(rp, plan.cycle.n) for rp in plan.robots}

    check_replayable = staticmethod(check_replayable)

    def last_uncovered(self, robot: int) -> int | None:
        """Highest cycle index (CCW from its first) of ``robot``'s region not yet covered."""
        first, size = self.regions[robot]
        n = self.cycle.n
        offsets = (first + np.arange(size)) % n
        open_offsets = np.flatnonzero(~self.covered[offsets])
        return None if open_offsets.size == 0 else int(offsets[open_offsets[-1]])

    def _decide(self) -> None:
        n = self.cycle.n
        while self.takeover and self.watching != self.robot and self.watching in self.dead:
            dead = self.watching
            self.watching = self.successor[dead]
            target = self.last_uncovered(dead)
            self._decisions.append(TakeoverDecision(dead, target))
            if target is not None:
                distance = (target - self.position) % n
                self._pending.extend((self.position + j) % n for j in range(1, distance + 1))
                return
