"""One robot's replica of the whole team, for running NCOCTA / COCTA as separate processes.

Every robot holds the same tree, robot count, algorithm and splits, and starts from the same
state (everyone on the root), so once it knows every robot's node at step t it computes the
same ``decide`` as everybody else and the same assignment of robots to moves: robots on a
node, in id order, take the node's moves in the order ``decide`` lists them; the rest stay.
The set up is ``run_coverage``'s, so a fleet run takes exactly the lockstep run's steps.
"""

from __future__ import annotations

from collections.abc import Mapping

from planner.errors import InfeasiblePlanError
from planner.treecover.rules import split_need
from planner.treecover.sim import default_splits
from planner.treecover.state import CoverageState
from planner.treecover.step import decide
from planner.treecover.types import Algo, Move, Splits, Tree


def assign(moves: list[Move], positions: list[int]) -> list[int]:
    """Where each robot (index) stands after ``moves``, given where each stood before."""
    by_node: dict[int, list[int]] = {}
    for robot, node in enumerate(positions):
        by_node.setdefault(node, []).append(robot)
    after = list(positions)
    for move in moves:
        queue = by_node.get(move.src, [])
        if len(queue) < move.count:
            raise ValueError(f"move {move} needs {move.count} robots on {move.src}, "
                             f"{len(queue)} left")
        for robot in queue[:move.count]:
            after[robot] = move.dst
        by_node[move.src] = queue[move.count:]
    return after


class TeamReplica:
    """The team's state as one robot sees it: ``positions[r]`` is robot r's node now."""

    def __init__(self, tree: Tree, robots: int, algo: Algo | str,
                 splits: Splits | None = None) -> None:
        self.algo = Algo(algo)
        self.splits = splits if splits is not None else default_splits(tree, robots, self.algo)
        self.state = CoverageState(tree, robots)
        if self.algo is Algo.COCTA:
            self.state.need = split_need(self.state, self.splits)
        self.positions = [0] * robots
        self.limit = 4 * tree.n * (tree.height + 2) + 16  # run_coverage's stall guard

    @property
    def step(self) -> int:
        return self.state.time

    def done(self) -> bool:
        """Every node visited and every robot back on the root."""
        return self.state.done()

    def disagreeing(self, reported: Mapping[int, int]) -> list[int]:
        """Robots whose reported node is not where this replica has them (should be none)."""
        return sorted(r for r, node in reported.items() if self.positions[r] != node)

    def advance(self) -> list[int]:
        """Decide and perform one synchronous step; return every robot's new node."""
        moves = decide(self.state, self.algo, self.splits)
        if not moves or self.state.time >= self.limit:
            raise InfeasiblePlanError(
                f"{self.algo.value} stalled at step {self.state.time} with "
                f"{self.state.robots} robots and splits {list(self.splits.heights)} "
                f"({self.state.remaining} nodes unvisited)")
        self.positions = assign(moves, self.positions)
        self.state.apply(moves)
        return list(self.positions)
