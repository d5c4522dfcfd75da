"""Offline robustness as pure discrete-time semantics: the lockstep replay of a plan.

simulate_failures replays a plan in unit time steps with fail-stop robots, driving one
OfflineRobot (planner.offline.machine) per robot with perfect knowledge. This is the oracle
the distributed agents are tested against. The time loop itself, :func:`replay`, is shared
with every family whose robots walk a plan and take over dead robots' work (the balanced
planner's robots, planner.balanced.machine): only the machines differ.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from planner.offline.machine import (
    MoveTo,
    OfflineRobot,
    RobotAction,
    TakeoverDecision,
    validate_replay,
)
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
    ids = [rp.robot for rp in plan.robots]
    cycle = plan.cycle
    shape = cycle.index.shape
    on = cycle.index >= 0
    machines = [OfflineRobot(plan, robot) for robot in ids]
    replayed = replay(machines, ids, [rp.start_index for rp in plan.robots], failures,
                      detection_delay, cycle.n, cycle.at)

    def spread(values: IntArray, fill: int) -> IntArray:
        out = np.full(shape, fill, dtype=np.int64)
        out[on] = values[cycle.index[on]]
        return out

    return replayed.result(spread)


class ReplayRobot(Protocol):
    """What the shared time loop asks of a robot's machine. Places are integer keys (a cycle
    index, a flat sub-cell index): the loop keeps its counts in arrays indexed by them."""

    def on_covered(self, key: int) -> None: ...

    def on_dead(self, robot: int) -> None: ...

    def on_moved(self) -> int: ...

    def next_action(self) -> RobotAction: ...

    def pop_decisions(self) -> list[TakeoverDecision]: ...


_NEVER = 1 << 62


@dataclass
class Replayed:
    """Counts of one replay in key space; ``result`` spreads them to the grid."""

    ids: list[int]
    walks: list[list[SubCell]]
    visits: IntArray
    first_robot: IntArray
    first_time: IntArray
    takeovers: list[Takeover]
    uncovered: int

    def result(self, spread: Callable[[IntArray, int], IntArray]) -> TakeoverResult:
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


def replay(machines: Sequence[ReplayRobot], ids: Sequence[int], starts: Sequence[int],
           failures: Mapping[int, int], delay: int, size: int,
           sub_of: Callable[[int], SubCell]) -> Replayed:
    """Unit-time lockstep of ``machines`` (positions in ``ids`` order) over ``size`` places.

    Robot ``ids[i]`` dies after ``failures[ids[i]]`` moves and is known dead ``delay`` steps
    later; every machine hears every arrival (perfect knowledge). When nobody can move until
    a failure becomes known, time jumps straight there.
    """
    fail = [failures.get(robot, _NEVER) for robot in ids]
    out = Replayed(list(ids), [[] for _ in ids], np.zeros(size, dtype=np.int64),
                   np.full(size, -1, dtype=np.int64), np.full(size, -1, dtype=np.int64),
                   [], size)

    def arrive(i: int, key: int, time: int) -> None:
        out.walks[i].append(sub_of(key))
        if out.visits[key] == 0:
            out.first_robot[key] = ids[i]
            out.first_time[key] = time
            out.uncovered -= 1
        out.visits[key] += 1
        for machine in machines:
            machine.on_covered(key)

    for i, key in enumerate(starts):
        arrive(i, key, 0)
    announced: set[int] = set()
    time = 0
    while True:
        for i, at in enumerate(fail):
            if i not in announced and at + delay <= time:
                announced.add(i)
                for machine in machines:
                    machine.on_dead(ids[i])
        movers = []
        for i, machine in enumerate(machines):
            if fail[i] <= time:
                continue
            action = machine.next_action()
            out.takeovers.extend(Takeover(ids[i], d.dead, time) for d in machine.pop_decisions())
            if isinstance(action, MoveTo):
                movers.append(i)
        if movers:
            for i in movers:
                arrive(i, machines[i].on_moved(), time + 1)
            time += 1
            continue
        if out.uncovered == 0:
            break
        later = [at + delay for at in fail if time < at + delay < _NEVER]
        if not later:
            break
        time = min(later)
    return out
