"""Offline MSTC robustness as pure discrete-time semantics (Alg. 2 / Alg. 4 of paper 003).

simulate_failures replays a plan in unit time steps with fail-stop robots and the takeover
rule: a robot that finished its own walk watches its successor along the cycle and, once the
successor is known dead, walks counter-clockwise into the dead robot's region up to its last
uncovered sub-cell, then watches the dead robot's successor. This is the oracle the lockstep
simulator and the distributed agents are tested against; docs/trees-and-metrics.md states the
rules in full.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from planner.errors import UnsupportedPlanError
from planner.types import BoolArray, IntArray, Plan, RobotPlan, SubCell


@dataclass(frozen=True)
class Takeover:
    """``taker`` took over the role of dead robot ``dead`` at time ``time``."""

    taker: int
    dead: int
    time: int


@dataclass(frozen=True, eq=False)
class TakeoverResult:
    """Outcome of simulate_failures, per robot in the plan's robot order.

    ``visits``, ``first_robot`` and ``first_time`` have the cycle index's shape: visit count,
    id of the robot that covered each sub-cell first and when (-1 where never covered or off
    the cycle). ``coverage_time`` is the time the last sub-cell got covered (None when
    incomplete); ``makespan`` is the largest number of moves of any robot.
    """

    robots: tuple[int, ...]
    walks: tuple[tuple[SubCell, ...], ...]
    visits: IntArray
    first_robot: IntArray
    first_time: IntArray
    takeovers: tuple[Takeover, ...]
    coverage_time: int | None
    complete: bool

    def __post_init__(self) -> None:
        for name in ("visits", "first_robot", "first_time"):
            array = np.ascontiguousarray(getattr(self, name))
            array.setflags(write=False)
            object.__setattr__(self, name, array)

    @property
    def moves(self) -> tuple[int, ...]:
        return tuple(len(w) - 1 for w in self.walks)

    @property
    def makespan(self) -> int:
        return max(self.moves, default=0)

    @property
    def covered(self) -> BoolArray:
        return self.visits > 0


def region_of(rp: RobotPlan, n: int) -> tuple[int, int]:
    """(first cycle index, size) of the interval a robot's legs cover, CCW from its first."""
    offset = low = high = 0
    for leg in rp.legs:
        offset += leg.direction.sign * leg.length
        low, high = min(low, offset), max(high, offset)
    return ((rp.start_index + low) % n, high - low + 1)


def simulate_failures(plan: Plan, failures: Mapping[int, int], *,
                      detection_delay: int = 0) -> TakeoverResult:
    """Replay ``plan`` when robot ``r`` fails at time ``failures[r]`` (after that many moves).

    Raises UnsupportedPlanError for non-unit speeds, walks that do not follow their legs along
    the cycle, regions that do not tile the cycle, unknown robots or negative times.
    """
    _validate(plan, failures, detection_delay)
    return _Simulation(plan, failures, detection_delay).run()


def _validate(plan: Plan, failures: Mapping[int, int], delay: int) -> None:
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


class _Simulation:
    """Mutable state of one replay; indices are positions in plan.robots unless named id."""

    def __init__(self, plan: Plan, failures: Mapping[int, int], delay: int) -> None:
        self.cycle = plan.cycle
        n = plan.cycle.n
        self.ids = [rp.robot for rp in plan.robots]
        k = len(self.ids)
        self.delay = delay
        never = 1 << 62
        self.fail = [failures.get(robot, never) for robot in self.ids]
        self.regions = [region_of(rp, n) for rp in plan.robots]
        order = sorted(range(k), key=lambda i: plan.robots[i].start_index)
        self.successor = [0] * k
        for a, b in zip(order, order[1:] + order[:1], strict=True):
            self.successor[a] = b
        self.watched = list(self.successor)
        self.pos = [rp.start_index for rp in plan.robots]
        self.pending = [deque(self.cycle.position((int(r), int(c))) for r, c in rp.path[1:])
                        for rp in plan.robots]
        self.walks: list[list[SubCell]] = [[] for _ in range(k)]
        self.visits = np.zeros(n, dtype=np.int64)
        self.first_robot = np.full(n, -1, dtype=np.int64)
        self.first_time = np.full(n, -1, dtype=np.int64)
        self.uncovered = n
        self.takeovers: list[Takeover] = []
        for i in range(k):
            self._arrive(i, self.pos[i], 0)

    def _arrive(self, i: int, index: int, time: int) -> None:
        self.pos[i] = index
        self.walks[i].append(self.cycle.at(index))
        if self.visits[index] == 0:
            self.first_robot[index] = self.ids[i]
            self.first_time[index] = time
            self.uncovered -= 1
        self.visits[index] += 1

    def _known_dead(self, i: int, time: int) -> bool:
        return self.fail[i] + self.delay <= time

    def _last_uncovered(self, region: tuple[int, int]) -> int | None:
        first, size = region
        n = self.cycle.n
        for offset in range(size - 1, -1, -1):
            index = (first + offset) % n
            if self.visits[index] == 0:
                return index
        return None

    def _decide(self, i: int, time: int) -> None:
        """An idle live robot: take over known-dead successors (chained) or keep waiting."""
        n = self.cycle.n
        while True:
            s = self.watched[i]
            if s == i or not self._known_dead(s, time):
                return
            self.takeovers.append(Takeover(self.ids[i], self.ids[s], time))
            self.watched[i] = self.successor[s]
            target = self._last_uncovered(self.regions[s])
            if target is not None:
                distance = (target - self.pos[i]) % n
                self.pending[i].extend((self.pos[i] + j) % n for j in range(1, distance + 1))
                return

    def _next_detection(self, time: int) -> int | None:
        later = [f + self.delay for f in self.fail if time < f + self.delay < (1 << 62)]
        return min(later, default=None)

    def run(self) -> TakeoverResult:
        time = 0
        k = len(self.ids)
        while True:
            if self.uncovered > 0:
                for i in range(k):
                    if not self.pending[i] and self.fail[i] > time:
                        self._decide(i, time)
            movers = [i for i in range(k) if self.pending[i] and self.fail[i] > time]
            if movers:
                for i in movers:
                    self._arrive(i, self.pending[i].popleft(), time + 1)
                time += 1
                continue
            if self.uncovered == 0:
                break
            # Nobody can move until a failure becomes known: jump straight there.
            detection = self._next_detection(time)
            if detection is None:
                break
            time = detection
        return self._result()

    def _result(self) -> TakeoverResult:
        shape = self.cycle.index.shape
        on = self.cycle.index >= 0

        def spread(values: IntArray, fill: int) -> IntArray:
            out = np.full(shape, fill, dtype=np.int64)
            out[on] = values[self.cycle.index[on]]
            return out

        complete = self.uncovered == 0
        return TakeoverResult(
            robots=tuple(self.ids),
            walks=tuple(tuple(w) for w in self.walks),
            visits=spread(self.visits, 0),
            first_robot=spread(self.first_robot, -1),
            first_time=spread(self.first_time, -1),
            takeovers=tuple(self.takeovers),
            coverage_time=int(self.first_time.max()) if complete else None,
            complete=complete,
        )
