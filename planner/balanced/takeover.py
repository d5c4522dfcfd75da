"""Robustness of balanced plans: a dead robot's region is finished by a live robot.

Pure discrete-time semantics in the style of planner.offline (paper 003, Alg. 2), for plans
whose robots walk their own regions rather than legs of one cycle. Robots form a ring in the
order of their starts along ``plan.cycle``. A live robot that has finished its walk watches
its successor; once the successor is known dead (``detection_delay`` steps after it failed)
the watcher takes over its role: it walks the shortest way (over the area's sub-cells) to
the nearer end of what is still uncovered of the dead robot's walk, follows that walk
(bridging any gap with a shortest path), and then watches the dead robot's successor. A
chain of dead robots is taken over one after the other, so with at least one robot alive
everything gets covered.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping

import numpy as np

from planner.errors import UnsupportedPlanError
from planner.invariants import InvariantViolation, check_path_moves
from planner.offline.lockstep import Takeover, TakeoverResult
from planner.types import BoolArray, IntArray, Plan, SubCell

_NEVER = 1 << 62


def simulate_failures(plan: Plan, failures: Mapping[int, int], *,
                      detection_delay: int = 0) -> TakeoverResult:
    """Replay ``plan`` when robot ``r`` fails at time ``failures[r]`` (after that many moves).

    Raises UnsupportedPlanError for non-unit speeds, paths that are not 4-adjacent walks on
    the plan's cycle sub-cells, unknown robots, or negative times.
    """
    _validate(plan, failures, detection_delay)
    return _Replay(plan, failures, detection_delay).run()


def _validate(plan: Plan, failures: Mapping[int, int], delay: int) -> None:
    ids = [rp.robot for rp in plan.robots]
    if not ids or len(set(ids)) != len(ids):
        raise UnsupportedPlanError(f"the plan's robot ids {ids} are empty or repeated")
    for robot, time in failures.items():
        if robot not in ids:
            raise UnsupportedPlanError(f"failure of robot {robot}: no such robot in the plan")
        if time < 0:
            raise UnsupportedPlanError(f"robot {robot} fails at time {time}; times are >= 0")
    if delay < 0:
        raise UnsupportedPlanError(f"detection delay {delay} is negative")
    on = plan.cycle.index >= 0
    for rp in plan.robots:
        if rp.speed != 1.0:
            raise UnsupportedPlanError(
                f"robot {rp.robot} has speed {rp.speed}: only unit-speed plans can be replayed")
        try:
            check_path_moves(rp.path)
        except InvariantViolation as exc:
            raise UnsupportedPlanError(f"robot {rp.robot}: {exc}") from exc
        if not all(on[r, c] for r, c in rp.path):
            raise UnsupportedPlanError(f"robot {rp.robot} walks off the plan's sub-cells")


class _Replay:
    """Mutable state of one replay; robots are positions in plan.robots unless named id."""

    def __init__(self, plan: Plan, failures: Mapping[int, int], delay: int) -> None:
        self.free: BoolArray = plan.cycle.index >= 0
        self.ids = [rp.robot for rp in plan.robots]
        k = len(self.ids)
        self.delay = delay
        self.fail = [failures.get(robot, _NEVER) for robot in self.ids]
        self.regions = [tuple(dict.fromkeys(rp.path)) for rp in plan.robots]
        order = sorted(range(k), key=lambda i: plan.robots[i].start_index)
        self.successor = [0] * k
        for a, b in zip(order, order[1:] + order[:1], strict=True):
            self.successor[a] = b
        self.watched = list(self.successor)
        self.pos = [rp.path[0] for rp in plan.robots]
        self.pending: list[deque[SubCell]] = [deque(rp.path[1:]) for rp in plan.robots]
        self.walks: list[list[SubCell]] = [[] for _ in range(k)]
        shape = self.free.shape
        self.visits = np.zeros(shape, dtype=np.int64)
        self.first_robot = np.full(shape, -1, dtype=np.int64)
        self.first_time = np.full(shape, -1, dtype=np.int64)
        self.uncovered = int(self.free.sum())
        self.takeovers: list[Takeover] = []
        for i in range(k):
            self._arrive(i, self.pos[i], 0)

    def _arrive(self, i: int, sub: SubCell, time: int) -> None:
        self.pos[i] = sub
        self.walks[i].append(sub)
        if self.visits[sub] == 0:
            self.first_robot[sub] = self.ids[i]
            self.first_time[sub] = time
            self.uncovered -= 1
        self.visits[sub] += 1

    def _known_dead(self, i: int, time: int) -> bool:
        return self.fail[i] + self.delay <= time

    def _decide(self, i: int, time: int) -> None:
        """An idle live robot takes over known-dead successors (chained) or keeps waiting."""
        while True:
            s = self.watched[i]
            if s == i or not self._known_dead(s, time):
                return
            self.takeovers.append(Takeover(self.ids[i], self.ids[s], time))
            self.watched[i] = self.successor[s]
            left = [sub for sub in self.regions[s] if self.visits[sub] == 0]
            if left:
                self.pending[i].extend(self._route(self.pos[i], left))
                return

    def _route(self, here: SubCell, left: list[SubCell]) -> list[SubCell]:
        """Shortest way to the nearer end of ``left``, then along it, bridging gaps."""
        dist = _distances(self.free, here)
        if dist[left[-1]] < dist[left[0]]:
            left = left[::-1]
        route: list[SubCell] = []
        at = here
        for sub in left:
            if abs(sub[0] - at[0]) + abs(sub[1] - at[1]) == 1:
                route.append(sub)
            elif sub != at:
                route.extend(_shortest_path(self.free, at, sub))
            at = sub
        return route

    def _next_detection(self, time: int) -> int | None:
        later = [f + self.delay for f in self.fail if time < f + self.delay < _NEVER]
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
            detection = self._next_detection(time)
            if detection is None:
                break
            time = detection
        complete = self.uncovered == 0
        return TakeoverResult(
            robots=tuple(self.ids), walks=tuple(tuple(w) for w in self.walks),
            visits=self.visits, first_robot=self.first_robot, first_time=self.first_time,
            takeovers=tuple(self.takeovers),
            coverage_time=int(self.first_time.max()) if complete else None,
            complete=complete)


def _bfs(free: BoolArray, source: SubCell) -> tuple[IntArray, dict[SubCell, SubCell]]:
    h, w = free.shape
    dist = np.full((h, w), _NEVER, dtype=np.int64)
    parent: dict[SubCell, SubCell] = {}
    dist[source] = 0
    queue = deque([source])
    while queue:
        r, c = queue.popleft()
        for nxt in ((r - 1, c), (r, c + 1), (r + 1, c), (r, c - 1)):
            if 0 <= nxt[0] < h and 0 <= nxt[1] < w and free[nxt] and dist[nxt] == _NEVER:
                dist[nxt] = dist[r, c] + 1
                parent[nxt] = (r, c)
                queue.append(nxt)
    return dist, parent


def _distances(free: BoolArray, source: SubCell) -> IntArray:
    return _bfs(free, source)[0]


def _shortest_path(free: BoolArray, a: SubCell, b: SubCell) -> list[SubCell]:
    """Sub-cells after ``a`` up to and including ``b`` on a shortest 4-connected path."""
    _, parent = _bfs(free, a)
    if b not in parent:
        raise UnsupportedPlanError(f"{b} cannot be reached from {a} over the plan's sub-cells")
    path = [b]
    while path[-1] != a:
        path.append(parent[path[-1]])
    return path[-2::-1]
