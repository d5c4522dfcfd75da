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
from collections.abc import Mapping

import numpy as np

from planner.errors import UnsupportedPlanError
from planner.invariants import InvariantViolation, check_path_moves
from planner.offline.machine import RingRobot, TakeoverDecision
from planner.types import BoolArray, IntArray, Plan, SubCell

_NEVER = 1 << 62


def validate_replay(plan: Plan, failures: Mapping[int, int], delay: int) -> None:
    """Raise UnsupportedPlanError unless ``plan`` can be replayed with ``failures``: unit
    speeds, 4-adjacent walks on the plan's cycle sub-cells, known robots, times >= 0."""
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


def check_replayable(plan: Plan) -> None:
    """Raise UnsupportedPlanError unless the takeover semantics can run ``plan``."""
    validate_replay(plan, {}, 0)


class BalancedRobot(RingRobot):
    """A balanced plan's robot: its own walk (walk-out and region), then takeovers along
    shortest paths to what is left of a dead robot's walk."""

    def __init__(self, plan: Plan, robot: int, *, takeover: bool = True) -> None:
        super().__init__(plan, robot, takeover=takeover)
        cycle = plan.cycle
        self.free: BoolArray = cycle.index >= 0
        self.regions = {rp.robot: tuple(dict.fromkeys(cycle.position(s) for s in rp.path))
                        for rp in plan.robots}

    check_replayable = staticmethod(check_replayable)

    def _decide(self) -> None:
        while self.takeover and self.watching != self.robot and self.watching in self.dead:
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
