"""A balanced plan's robot as a sans-I/O state machine: walk my region, then take over.

Robots form a ring in the order of their starts along ``plan.cycle``. A robot that finished
its walk watches its successor; once the successor is known dead it takes over its role: it
walks the shortest way (over the area's sub-cells) to the nearer end of what is still
uncovered of the dead robot's walk, follows that walk (bridging any gap with a shortest
path), and then watches the dead robot's successor. A chain of dead robots is taken over one
after the other, so with at least one robot alive everything gets covered.

The interface is OfflineRobot's (planner.offline.machine), with places as cycle indices, so
the shared lockstep loop (planner.offline.lockstep.replay) drives both families.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from planner.errors import UnsupportedPlanError
from planner.offline.machine import Finished, MoveTo, RobotAction, TakeoverDecision, WaitFor
from planner.types import BoolArray, IntArray, Plan, SubCell

_NEVER = 1 << 62


class BalancedRobot:
    """Feed it :meth:`on_covered` (any robot stood on a cycle index), :meth:`on_dead` and
    :meth:`on_moved`; ask :meth:`next_action`. Every start is covered from the outset."""

    def __init__(self, plan: Plan, robot: int) -> None:
        by_id = {rp.robot: rp for rp in plan.robots}
        if robot not in by_id:
            raise UnsupportedPlanError(f"robot {robot} is not in the plan")
        cycle = self.cycle = plan.cycle
        self.robot = robot
        self.free: BoolArray = cycle.index >= 0
        self.regions = {rp.robot: tuple(dict.fromkeys(cycle.position(s) for s in rp.path))
                        for rp in plan.robots}
        order = sorted(by_id, key=lambda r: by_id[r].start_index)
        self.successor = dict(zip(order, order[1:] + order[:1], strict=True))
        self.watching = self.successor[robot]
        mine = by_id[robot]
        self.position = cycle.position(mine.path[0])
        self._pending = deque(cycle.position(s) for s in mine.path[1:])
        self.covered = np.zeros(cycle.n, dtype=bool)
        self._uncovered = cycle.n
        self.dead: set[int] = set()
        self._decisions: list[TakeoverDecision] = []
        for rp in plan.robots:
            self.on_covered(cycle.position(rp.path[0]))

    @property
    def all_covered(self) -> bool:
        return self._uncovered == 0

    def on_covered(self, index: int) -> None:
        if not self.covered[index]:
            self.covered[index] = True
            self._uncovered -= 1

    def on_dead(self, robot: int) -> None:
        self.dead.add(robot)

    def on_moved(self) -> int:
        index = self._pending.popleft()
        self.position = index
        self.on_covered(index)
        return index

    def next_action(self) -> RobotAction:
        if not self._pending and not self.all_covered:
            self._decide()
        if self._pending:
            index = self._pending[0]
            return MoveTo(index, self.cycle.at(index))
        if self.all_covered:
            return Finished()
        return WaitFor(self.watching)

    def pop_decisions(self) -> list[TakeoverDecision]:
        out, self._decisions = self._decisions, []
        return out

    def _decide(self) -> None:
        while self.watching != self.robot and self.watching in self.dead:
            dead = self.watching
            self.watching = self.successor[dead]
            left = [self.cycle.at(i) for i in self.regions[dead] if not self.covered[i]]
            target = self.cycle.position(left[-1]) if left else None
            self._decisions.append(TakeoverDecision(dead, target))
            if left:
                route = self._route(self.cycle.at(self.position), left)
                self._pending.extend(self.cycle.position(s) for s in route)
                return

    def _route(self, here: SubCell, left: list[SubCell]) -> list[SubCell]:
        """Shortest way to the nearer end of ``left``, then along it, bridging gaps."""
        dist = _bfs(self.free, here)[0]
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


def _shortest_path(free: BoolArray, a: SubCell, b: SubCell) -> list[SubCell]:
    """Sub-cells after ``a`` up to and including ``b`` on a shortest 4-connected path."""
    _, parent = _bfs(free, a)
    if b not in parent:
        raise UnsupportedPlanError(f"{b} cannot be reached from {a} over the plan's sub-cells")
    path = [b]
    while path[-1] != a:
        path.append(parent[path[-1]])
    return path[-2::-1]
