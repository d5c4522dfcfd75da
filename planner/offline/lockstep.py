"""Offline robustness as pure discrete-time semantics: the lockstep replay of a plan.

simulate_failures replays a plan in unit time steps with fail-stop robots, driving one
OfflineRobot (planner.offline.machine) per robot with perfect knowledge. This is the oracle
the distributed agents are tested against. The time loop itself, :func:`replay`, is shared
with every family whose robots walk a plan and take over dead robots' work (the balanced
planner's robots, planner.balanced.machine): only the machines differ.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from planner.offline.machine import (
    MoveTo,
    OfflineRobot,
    RobotAction,
    TakeoverDecision,
    validate_replay,
)
from planner.offline.rebalance import (
    DEFAULT_RECOVERY,
    Recovery,
    Replan,
    Survivor,
    plan_order,
    rebalance,
)
from planner.offline.traffic import Go, Peer, Traffic, TrafficCounts
from planner.types import BoolArray, Cycle, IntArray, Plan, SubCell

Replanner = Callable[[BoolArray, Sequence[Survivor]], Replan]


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
    incomplete); ``makespan`` is the largest number of moves of any robot. With bodies
    (``recovery="rebalance"``: planner.offline.traffic deconflicts the walks), ``traffic``
    holds each robot's waits, detours and bumps, and ``timeline`` the cycle index each body
    stands on (-1: gone) at time 0 and after every step in which a body moved (the
    positions in between are the same), one column per robot.
    """

    robots: tuple[int, ...]
    walks: tuple[tuple[SubCell, ...], ...]
    visits: IntArray
    first_robot: IntArray
    first_time: IntArray
    takeovers: tuple[Takeover, ...]
    coverage_time: int | None
    complete: bool
    traffic: tuple[TrafficCounts, ...] = ()
    timeline: IntArray = field(default_factory=lambda: np.zeros((0, 0), dtype=np.int64))

    def __post_init__(self) -> None:
        for name in ("visits", "first_robot", "first_time", "timeline"):
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
                      detection_delay: int = 0,
                      recovery: Recovery = DEFAULT_RECOVERY) -> TakeoverResult:
    """Replay ``plan`` when robot ``r`` fails at time ``failures[r]`` (after that many moves).

    ``recovery`` "rebalance" (the default) re-plans at each known death
    (planner.offline.rebalance), nobody takes over, and the robots are bodies: one per
    sub-cell, entering only sub-cells no body holds, their walks deconflicted by
    planner.offline.traffic. "takeover" is the papers' ring takeover, replayed as the papers
    do (robots as points: no waits).

    Raises UnsupportedPlanError for non-unit speeds, walks that do not follow their legs along
    the cycle, regions that do not tile the cycle, unknown robots or negative times.
    """
    validate_replay(plan, failures, detection_delay)
    ids = [rp.robot for rp in plan.robots]
    cycle = plan.cycle
    shape = cycle.index.shape
    on = cycle.index >= 0
    machines = [OfflineRobot(plan, robot, takeover=recovery == "takeover") for robot in ids]
    replayed = replay(machines, ids, [rp.start_index for rp in plan.robots], failures,
                      detection_delay, cycle.n, cycle.at, replanner(plan, recovery),
                      bodies=cycle if recovery == "rebalance" else None)

    def spread(values: IntArray, fill: int) -> IntArray:
        out = np.full(shape, fill, dtype=np.int64)
        out[on] = values[cycle.index[on]]
        return out

    return replayed.result(spread)


def replanner(plan: Plan, recovery: Recovery) -> Replanner | None:
    """The re-plan the lockstep runs at each known death, None for the takeover."""
    if recovery == "takeover":
        return None
    rank = plan_order(plan)

    def replan(covered: BoolArray, survivors: Sequence[Survivor]) -> Replan:
        return rebalance(plan.cycle, covered, survivors, rank)

    return replan


class ReplayRobot(Protocol):
    """What the shared time loop asks of a robot's machine. Places are integer keys (a cycle
    index, a flat sub-cell index): the loop keeps its counts in arrays indexed by them."""

    def on_covered(self, key: int) -> None: ...

    def on_dead(self, robot: int) -> None: ...

    def on_moved(self) -> int: ...

    def next_action(self) -> RobotAction: ...

    def pop_decisions(self) -> list[TakeoverDecision]: ...

    @property
    def position(self) -> int: ...

    @property
    def pending_route(self) -> tuple[int, ...]: ...

    def on_replan(self, route: tuple[int, ...]) -> None: ...


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
    traffic: list[TrafficCounts] = field(default_factory=list)
    timeline: list[list[int]] = field(default_factory=list)

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
            traffic=tuple(self.traffic),
            timeline=np.array(self.timeline, dtype=np.int64).reshape(-1, len(self.ids)),
        )


def replay(machines: Sequence[ReplayRobot], ids: Sequence[int], starts: Sequence[int],
           failures: Mapping[int, int], delay: int, size: int,
           sub_of: Callable[[int], SubCell], replan: Replanner | None = None, *,
           bodies: Cycle | None = None) -> Replayed:
    """Unit-time lockstep of ``machines`` (positions in ``ids`` order) over ``size`` places.

    Robot ``ids[i]`` dies after ``failures[ids[i]]`` moves and is known dead ``delay`` steps
    later; every machine hears every arrival (perfect knowledge). When nobody can move until
    a failure becomes known, time jumps straight there. With ``replan``, each time deaths
    become known the robots not known dead get their new routes from
    ``replan(covered, survivors).routes``, computed once from what they all know.

    With ``bodies`` (the cycle the places index), robots are bodies as in simhw: a body
    enters only a place no body held at the start of the step (a dead one's until its death
    is known), of two racing for a place the lower id gets it and the other bumps, and each
    robot's planner.offline.traffic.Traffic decides from every body's place and next places.
    """
    fail = [failures.get(robot, _NEVER) for robot in ids]
    out = Replayed(list(ids), [[] for _ in ids], np.zeros(size, dtype=np.int64),
                   np.full(size, -1, dtype=np.int64), np.full(size, -1, dtype=np.int64),
                   [], size)
    lanes = None if bodies is None else [Traffic(robot, bodies, key)
                                         for robot, key in zip(ids, starts, strict=True)]
    if lanes is not None:
        out.traffic = [lane.counts for lane in lanes]

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
    gone = [False] * len(ids)
    if lanes is not None:
        out.timeline.append(list(starts))
    limit = 20 * size + max((at for at in fail if at < _NEVER), default=0) + delay
    time = 0
    while time <= limit:
        news = False
        for i, at in enumerate(fail):
            if i not in announced and at + delay <= time:
                announced.add(i)
                gone[i] = True
                news = True
                for machine in machines:
                    machine.on_dead(ids[i])
        if news and replan is not None:
            alive = [i for i in range(len(machines)) if i not in announced]
            routes = replan(out.visits > 0, [
                Survivor(ids[i], machines[i].position, machines[i].pending_route)
                if lanes is None else
                Survivor(ids[i], lanes[i].at, lanes[i].walk(machines[i].pending_route))
                for i in alive])
            for i in alive:
                machines[i].on_replan(routes.routes[ids[i]])
                if lanes is not None:
                    lanes[i].rejoin()
        actions: dict[int, RobotAction] = {}
        for i, machine in enumerate(machines):
            if fail[i] <= time:
                continue
            actions[i] = machine.next_action()
            out.takeovers.extend(Takeover(ids[i], d.dead, time) for d in machine.pop_decisions())
        if lanes is None:
            movers = [i for i, action in actions.items() if isinstance(action, MoveTo)]
            for i in movers:
                arrive(i, machines[i].on_moved(), time + 1)
        else:
            movers = _step_bodies(machines, lanes, actions, gone, fail, time, arrive,
                                  out.timeline)
        if movers:
            time += 1
            continue
        if out.uncovered == 0:
            break
        later = [at + delay for at in fail if time < at + delay < _NEVER]
        if not later:
            break
        time = min(later)
    return out


def _step_bodies(machines: Sequence[ReplayRobot], lanes: list[Traffic],
                 actions: Mapping[int, RobotAction], gone: list[bool], fail: list[int],
                 time: int, arrive: Callable[[int, int, int], None],
                 timeline: list[list[int]]) -> list[int]:
    """One step of bodies: every live robot's Traffic decides from the others' places and
    next places at the start of the step; moves into free places are made, lowest id first
    on a race. Returns the robots that moved (or walked on a plan step in place)."""
    present = [i for i in range(len(lanes)) if not gone[i]]
    seen = {i: Peer(lanes[i].robot, lanes[i].at) if fail[i] <= time
            else lanes[i].peer(machines[i].pending_route) for i in present}
    held = {lanes[i].at for i in present}
    taken: set[int] = set()
    progressed: list[int] = []
    moves: list[tuple[int, Go]] = []
    for i in sorted(actions, key=lambda i: lanes[i].robot):
        action = actions[i]
        peers = [seen[j] for j in present if j != i]
        step = lanes[i].decide(action.index if isinstance(action, MoveTo) else None, peers)
        if not isinstance(step, Go):
            continue
        if step.target == lanes[i].at:
            machines[i].on_moved()
            progressed.append(i)
        elif step.target in held or step.target in taken:
            lanes[i].bumped()
        else:
            taken.add(step.target)
            moves.append((i, step))
    for i, step in moves:
        key = machines[i].on_moved() if step.on_plan else step.target
        lanes[i].moved(step)
        arrive(i, key, time + 1)
        progressed.append(i)
    if moves:
        row = [-1] * len(lanes)
        for i in present:
            row[i] = lanes[i].at
        timeline.append(row)
    return progressed
