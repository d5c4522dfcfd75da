"""One robot's replica of the whole team, for running NCOCTA / COCTA as separate processes.

Every robot holds the same tree, robot count, algorithm and splits, and starts from the same
state (everyone on the root), so once it knows every robot's node at step t it computes the
same ``decide`` as everybody else and the same assignment of robots to moves: robots on a
node, in id order, take the node's moves in the order ``decide`` lists them; the rest stay.
The set up is ``run_coverage``'s, so a fleet run takes exactly the lockstep run's steps.

Robots that die are removed between steps (:meth:`TeamReplica.remove`); the next step then
refills the node a dead robot leaves empty (planner.treecover.repair). If the survivors stall
under the splits, the team gathers on its top node and re-plans: first with the splits the
algorithm picks for the survivors, then, should that stall too, with no split at all (the
whole team walks one depth-first search, which always finishes). The same replica drives the
lockstep runs with failures (planner.treecover.failures), so both take the same steps.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

from planner.errors import InfeasiblePlanError
from planner.treecover.repair import gather_moves, refill_moves
from planner.treecover.rules import split_need
from planner.treecover.sim import default_splits, initial_state
from planner.treecover.step import decide
from planner.treecover.types import Algo, Move, Splits, Tree


def assign(moves: list[Move], positions: list[int],
           alive: list[bool] | None = None) -> list[int]:
    """Where each robot (index) stands after ``moves``, given where each stood before; robots
    not ``alive`` neither move nor take moves."""
    by_node: dict[int, list[int]] = {}
    for robot, node in enumerate(positions):
        if alive is None or alive[robot]:
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
    """The team's state as one robot sees it: ``positions[r]`` is robot r's node now (a dead
    robot's: where it was to stand when it was removed)."""

    def __init__(self, tree: Tree, robots: int, algo: Algo | str,
                 splits: Splits | None = None) -> None:
        self.tree = tree
        self.algo = Algo(algo)
        self.splits, self.state = initial_state(tree, robots, self.algo, splits)
        self.positions = [0] * robots
        self.alive = [True] * robots
        self.removed: dict[int, int] = {}  # dead robot -> the step after which it was removed
        self.replans: list[tuple[int, Splits]] = []  # (step, splits) of every re-plan
        self.gathering = False
        self.limit = 4 * tree.n * (tree.height + 2) + 16  # run_coverage's stall guard

    @property
    def step(self) -> int:
        return self.state.time

    def done(self) -> bool:
        """Every node visited and every live robot back on the root."""
        return self.state.done()

    def disagreeing(self, reported: Mapping[int, int]) -> list[int]:
        """Live robots whose reported node is not where this replica has them."""
        return sorted(r for r, node in reported.items()
                      if self.alive[r] and self.positions[r] != node)

    def remove(self, robots: Iterable[int]) -> None:
        """These robots were lost on their way into the current step: the team moved as if
        they would arrive, they did not. A node only such a robot was entering stays
        unvisited. The next :meth:`advance` repairs the trail."""
        state = self.state
        for robot in sorted(set(robots)):
            if not self.alive[robot]:
                continue
            node = self.positions[robot]
            alone = state.at[node] == 1
            state.remove(node)
            if alone and node != 0 and state.visit_time[node] == state.time:
                state.unvisit(node)
            self.alive[robot] = False
            self.removed[robot] = self.step

    def advance(self) -> list[int]:
        """Decide and perform one synchronous step; return every robot's new node."""
        moves = self._next_moves()
        if not moves or self.state.time >= self.limit:
            raise InfeasiblePlanError(
                f"{self.algo.value} stalled at step {self.state.time} with "
                f"{self.state.robots} robots and splits {list(self.splits.heights)} "
                f"({self.state.remaining} nodes unvisited)")
        self.positions = assign(moves, self.positions, self.alive)
        self.state.apply(moves)
        return list(self.positions)

    def _next_moves(self) -> list[Move]:
        if self.removed:
            refill = refill_moves(self.state)
            if refill:
                return refill
        if self.gathering:
            moves = gather_moves(self.state)
            if moves:
                return moves
            self._replan()
        moves = decide(self.state, self.algo, self.splits)
        if moves or not self.removed or self.done():
            return moves
        # the survivors stall under these splits: regroup on the top node, then re-plan
        self.gathering = True
        moves = gather_moves(self.state)
        if moves:
            return moves
        self._replan()
        return decide(self.state, self.algo, self.splits)

    def _replan(self) -> None:
        """Splits for the survivors; no split at all if those stalled already."""
        self.gathering = False
        tried = {splits for _, splits in self.replans}
        fresh = default_splits(self.tree, self.state.robots, self.algo)
        self.splits = fresh if fresh not in tried and fresh != self.splits else Splits(())
        if self.algo is Algo.COCTA:
            self.state.need = split_need(self.state, self.splits)
        self.replans.append((self.step, self.splits))
