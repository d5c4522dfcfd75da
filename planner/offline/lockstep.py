"""Offline MSTC robustness as pure discrete-time semantics: the lockstep replay of a plan.

simulate_failures replays a plan in unit time steps with fail-stop robots, driving one
OfflineRobot (planner.offline.machine) per robot with perfect knowledge. This is the oracle
the distributed agents are tested against.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from planner.offline.machine import MoveTo, OfflineRobot, validate_replay
from planner.types import BoolArray, IntArray, Plan, SubCell


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


def simulate_failures(plan: Plan, failures: Mapping[int, int], *,
                      detection_delay: int = 0) -> TakeoverResult:
    """Replay ``plan`` when robot ``r`` fails at time ``failures[r]`` (after that many moves).

    Raises UnsupportedPlanError for non-unit speeds, walks that do not follow their legs along
    the cycle, regions that do not tile the cycle, unknown robots or negative times.
    """
    validate_replay(plan, failures, detection_delay)
    return _Simulation(plan, failures, detection_delay).run()


class _Simulation:
    """Lockstep driver of one OfflineRobot per plan robot; indices are positions in
    plan.robots unless named id. Every machine hears every arrival (perfect knowledge)."""

    def __init__(self, plan: Plan, failures: Mapping[int, int], delay: int) -> None:
        self.cycle = plan.cycle
        n = plan.cycle.n
        self.ids = [rp.robot for rp in plan.robots]
        self.delay = delay
        never = 1 << 62
        self.fail = [failures.get(robot, never) for robot in self.ids]
        self.machines = [OfflineRobot(plan, robot) for robot in self.ids]
        self.announced: set[int] = set()
        self.walks: list[list[SubCell]] = [[] for _ in self.ids]
        self.visits = np.zeros(n, dtype=np.int64)
        self.first_robot = np.full(n, -1, dtype=np.int64)
        self.first_time = np.full(n, -1, dtype=np.int64)
        self.uncovered = n
        self.takeovers: list[Takeover] = []
        for i, rp in enumerate(plan.robots):
            self._arrive(i, rp.start_index, 0)

    def _arrive(self, i: int, index: int, time: int) -> None:
        self.walks[i].append(self.cycle.at(index))
        if self.visits[index] == 0:
            self.first_robot[index] = self.ids[i]
            self.first_time[index] = time
            self.uncovered -= 1
        self.visits[index] += 1
        for machine in self.machines:
            machine.on_covered(index)

    def _announce_deaths(self, time: int) -> None:
        for i, fail in enumerate(self.fail):
            if i not in self.announced and fail + self.delay <= time:
                self.announced.add(i)
                for machine in self.machines:
                    machine.on_dead(self.ids[i])

    def _next_detection(self, time: int) -> int | None:
        later = [f + self.delay for f in self.fail if time < f + self.delay < (1 << 62)]
        return min(later, default=None)

    def run(self) -> TakeoverResult:
        time = 0
        while True:
            self._announce_deaths(time)
            movers = []
            for i, machine in enumerate(self.machines):
                if self.fail[i] <= time:
                    continue
                action = machine.next_action()
                self.takeovers.extend(Takeover(self.ids[i], d.dead, time)
                                      for d in machine.pop_decisions())
                if isinstance(action, MoveTo):
                    movers.append(i)
            if movers:
                for i in movers:
                    self._arrive(i, self.machines[i].on_moved(), time + 1)
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
