"""What a tree-coverage fleet did, judged from the robots' own reports alone (sans I/O).

The launcher listens to every outbox (it is not a robot: the radio's range does not apply to
it) and keeps, per step, each robot's node from the reports robots make about themselves.
From those alone it checks the run independently of the agents' replicas: every step's
occupied nodes connected (Lemma 4.1), every walk along one tree edge at most, every node
visited, and the coverage time (the first step with all nodes visited and all robots on the
root).

Robots die: a step is complete once every robot the reports of that step do not list as
``gone`` has reported, or once a report of the next step lists the missing ones as gone (the
team removed them at this step: it is a *death step*). At a death step the dead robot may
have been the only link between two parts of the team, so connectivity is judged there
separately (``cut_at_death``): the team cannot be connected without it until the repair step.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass, field

from bus.messages import TreeReport
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
    connected: bool  # at every step that is not a death step
    jumps: int  # walks that were not along one tree edge (or staying)
    transmissions: int
    max_occupied: int
    deaths: dict[int, int] = field(default_factory=dict)  # robot -> step it was removed at
    cut_at_death: int = 0  # death steps at which the live robots were not connected


class TeamObserver:
    """Feeds on every transmission; ``run()`` summarises."""

    def __init__(self, tree: Tree, robots: int) -> None:
        self.parent: list[int] = tree.parent.tolist()
        self.robots = robots
        self.nodes: dict[int, dict[int, int]] = {}  # step -> robot -> node (own reports)
        self.gone: dict[int, set[int]] = {}  # step -> robots removed before it
        self.seen = [False] * tree.n
        self.visited = 0
        self.complete = -1  # last step whose every own report has been seen
        self.coverage_time: int | None = None
        self.connected = True
        self.jumps = 0
        self.transmissions = 0
        self.max_occupied = 0
        self.deaths: dict[int, int] = {}
        self.cut_at_death = 0
        self._last: dict[int, int] | None = None

    def on_transmission(self, report: TreeReport) -> None:
        self.transmissions += 1
        if report.robot != report.sender or not 0 <= report.robot < self.robots \
                or not 0 <= report.node < len(self.parent) or report.step <= self.complete:
            return
        self.nodes.setdefault(report.step, {})[report.robot] = report.node
        self.gone.setdefault(report.step, {robot for robot, _ in report.gone})
        while self._closable(self.complete + 1):
            self._close_step(self.complete + 1)

    def _closable(self, step: int) -> bool:
        if step not in self.gone:
            return False
        missing = self._expected(step) - self.nodes[step].keys()
        return not missing or missing <= self.gone.get(step + 1, set())

    def _expected(self, step: int) -> set[int]:
        return set(range(self.robots)) - self.gone[step]

    def _close_step(self, step: int) -> None:
        where = self.nodes.pop(step)
        missing = self._expected(step) - where.keys()
        occupied = set(where.values())
        if missing:
            self.deaths.update((robot, step) for robot in missing)
            self.cut_at_death += not connected(self.parent, occupied)
        else:
            self.connected = self.connected and connected(self.parent, occupied)
        self.max_occupied = max(self.max_occupied, len(occupied))
        if self._last is not None:
            self.jumps += sum(1 for r, b in where.items() if r in self._last
                              and (a := self._last[r]) != b
                              and self.parent[a] != b and self.parent[b] != a)
        self._last = where
        for v in occupied:
            if not self.seen[v]:
                self.seen[v] = True
                self.visited += 1
        if self.coverage_time is None and self.visited == len(self.seen) \
                and occupied == {0}:
            self.coverage_time = step
        self.gone.pop(step, None)
        self.complete = step

    def finish(self, lost: Collection[int]) -> None:
        """The agents have all ended: close the steps whose missing reports are only from
        ``lost`` robots (a robot lost at the last step has no next step to confirm it)."""
        while (step := self.complete + 1) in self.gone \
                and self._expected(step) - self.nodes[step].keys() <= set(lost):
            self._close_step(step)

    def run(self) -> ObservedRun:
        return ObservedRun(steps=self.complete + 1, coverage_time=self.coverage_time,
                           visited=self.visited, nodes=len(self.seen),
                           connected=self.connected, jumps=self.jumps,
                           transmissions=self.transmissions, max_occupied=self.max_occupied,
                           deaths=dict(self.deaths), cut_at_death=self.cut_at_death)
