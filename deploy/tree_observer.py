"""What a tree-coverage fleet did, judged from the robots' own reports alone (sans I/O).

The launcher listens to every outbox (it is not a robot: the radio's range does not apply to
it) and keeps, per step, each robot's node from the reports robots make about themselves.
From those alone it checks the run independently of the agents' replicas: every step's
occupied nodes connected (Lemma 4.1), every walk along one tree edge at most, every node
visited, and the coverage time (the first step with all nodes visited and all robots on the
root).
"""

from __future__ import annotations

from dataclasses import dataclass

from bus.tree_messages import TreeReport
from planner.treecover.types import Tree


def connected(parent: list[int], occupied: set[int]) -> bool:
    """Occupied nodes induce one connected subtree: exactly one has no occupied parent."""
    return sum(1 for v in occupied if parent[v] < 0 or parent[v] not in occupied) == 1


@dataclass
class ObservedRun:
    steps: int  # steps whose every report was seen
    coverage_time: int | None
    visited: int
    nodes: int
    connected: bool
    jumps: int  # walks that were not along one tree edge (or staying)
    transmissions: int
    max_occupied: int


class TeamObserver:
    """Feeds on every transmission; ``run()`` summarises."""

    def __init__(self, tree: Tree, robots: int) -> None:
        self.parent: list[int] = tree.parent.tolist()
        self.robots = robots
        self.nodes: dict[int, dict[int, int]] = {}  # step -> robot -> node (own reports)
        self.seen = [False] * tree.n
        self.visited = 0
        self.complete = -1  # last step whose every own report has been seen
        self.coverage_time: int | None = None
        self.connected = True
        self.jumps = 0
        self.transmissions = 0
        self.max_occupied = 0
        self._last: list[int] | None = None

    def on_transmission(self, report: TreeReport) -> None:
        self.transmissions += 1
        if report.robot != report.sender or not 0 <= report.robot < self.robots \
                or not 0 <= report.node < len(self.parent) or report.step <= self.complete:
            return
        self.nodes.setdefault(report.step, {})[report.robot] = report.node
        while len(self.nodes.get(self.complete + 1, {})) == self.robots:
            self._close_step(self.complete + 1)

    def _close_step(self, step: int) -> None:
        where = self.nodes.pop(step)
        positions = [where[r] for r in range(self.robots)]
        occupied = set(positions)
        self.connected = self.connected and connected(self.parent, occupied)
        self.max_occupied = max(self.max_occupied, len(occupied))
        if self._last is not None:
            self.jumps += sum(1 for a, b in zip(self._last, positions, strict=True)
                              if a != b and self.parent[a] != b and self.parent[b] != a)
        self._last = positions
        for v in occupied:
            if not self.seen[v]:
                self.seen[v] = True
                self.visited += 1
        if self.coverage_time is None and self.visited == len(self.seen) \
                and occupied == {0}:
            self.coverage_time = step
        self.complete = step

    def run(self) -> ObservedRun:
        return ObservedRun(steps=self.complete + 1, coverage_time=self.coverage_time,
                           visited=self.visited, nodes=len(self.seen),
                           connected=self.connected, jumps=self.jumps,
                           transmissions=self.transmissions, max_occupied=self.max_occupied)
