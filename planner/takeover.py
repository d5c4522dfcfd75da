"""Offline MSTC robustness as pure discrete-time semantics (Alg. 2 / Alg. 4 of paper 003).

simulate_failures replays a plan in unit time steps with fail-stop robots and the takeover
rule: a robot that finished its own walk watches its successor along the cycle and, once the
successor is known dead, walks counter-clockwise into the dead robot's region up to its last
uncovered sub-cell, then watches the dead robot's successor. This is the oracle the lockstep
simulator and the distributed agents are tested against; docs/trees-and-metrics.md states the
rules in full.

The per-robot decisions live in one sans-I/O state machine, OfflineRobot: simulate_failures
drives one per robot in lockstep with perfect knowledge, and the agent process (agent/)
drives its own from the bus and the body, so the oracle and the fleet run the same code.
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


# ---- the per-robot decision logic, shared by the lockstep replay and the agent -------------


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


def check_replayable(plan: Plan) -> None:
    """Raise UnsupportedPlanError unless the takeover semantics can run ``plan``."""
    _validate(plan, {}, 0)


class OfflineRobot:
    """One robot's offline MSTC life as a sans-I/O state machine (Alg. 2 / Alg. 4).

    Feed it what the robot learns — :meth:`on_covered` (anyone covered a cycle index),
    :meth:`on_dead` (a robot is known dead), :meth:`on_moved` (my last MoveTo is done) — and
    ask :meth:`next_action`. Every start is covered from the outset. The robot walks its own
    plan; then, while coverage is incomplete, it watches its successor along the cycle and,
    once that one is known dead, walks CCW to the last uncovered sub-cell of its region and
    watches the dead robot's successor (chained). Decisions are kept for :meth:`pop_decisions`.
    """

    def __init__(self, plan: Plan, robot: int) -> None:
        n = plan.cycle.n
        by_id = {rp.robot: rp for rp in plan.robots}
        if robot not in by_id:
            raise UnsupportedPlanError(f"robot {robot} is not in the plan")
        self.robot = robot
        self.cycle = plan.cycle
        self.regions = {rp.robot: region_of(rp, n) for rp in plan.robots}
        order = sorted(by_id, key=lambda r: by_id[r].start_index)
        self.successor = dict(zip(order, order[1:] + order[:1], strict=True))
        self.watching = self.successor[robot]
        mine = by_id[robot]
        self.position = mine.start_index
        self._pending = deque(plan.cycle.position(sub) for sub in mine.path[1:])
        self.own_steps_left = len(self._pending)
        self.covered = np.zeros(n, dtype=bool)
        self._uncovered = n
        self.dead: set[int] = set()
        self._decisions: list[TakeoverDecision] = []
        for rp in plan.robots:
            self.on_covered(rp.start_index)

    @property
    def all_covered(self) -> bool:
        return self._uncovered == 0

    @property
    def about_to_take_over(self) -> bool:
        """True when the next :meth:`next_action` will decide a takeover (idle, coverage
        incomplete, the watched robot known dead): a driver may first refresh its knowledge."""
        return (not self._pending and not self.all_covered and self.watching != self.robot
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

    def pop_decisions(self) -> list[TakeoverDecision]:
        """Takeovers decided since the last call, in order."""
        out, self._decisions = self._decisions, []
        return out

    def last_uncovered(self, robot: int) -> int | None:
        """Highest cycle index (CCW from its first) of ``robot``'s region not yet covered."""
        first, size = self.regions[robot]
        n = self.cycle.n
        offsets = (first + np.arange(size)) % n
        open_offsets = np.flatnonzero(~self.covered[offsets])
        return None if open_offsets.size == 0 else int(offsets[open_offsets[-1]])

    def _decide(self) -> None:
        n = self.cycle.n
        while self.watching != self.robot and self.watching in self.dead:
            dead = self.watching
            self.watching = self.successor[dead]
            target = self.last_uncovered(dead)
            self._decisions.append(TakeoverDecision(dead, target))
            if target is not None:
                distance = (target - self.position) % n
                self._pending.extend((self.position + j) % n for j in range(1, distance + 1))
                return
