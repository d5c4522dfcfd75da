"""The paper's loop as a clock: one iteration of Algorithm 1 / 2 is one time unit.

Algorithms 1 and 2 visit the occupied nodes "from the lowest to the highest height" and move
robots as they go. Read as an in-place pass, robots that climb into a node are handled again
when that node's turn comes, so in one iteration a robot may climb any number of edges and then
walk one edge down. :func:`planner.treecover.sim.run_coverage` lets every robot walk one edge
per step (the convention of Lemma 4.3's proof); this driver counts iterations instead, which
is the convention under which our COCTA reproduces the paper's worked figure (section 4.3:
SF 8.6 with 20 robots on a 3-ary tree of height 7). The node rules are the same.
"""

from __future__ import annotations

import heapq

from planner.treecover.sim import drive
from planner.treecover.state import CoverageState
from planner.treecover.step import NodeRule, rule_for
from planner.treecover.types import Algo, CoverageResult, Move, Splits, Tree


def run_loop_iterations(tree: Tree, robots: int, algo: Algo | str,
                        splits: Splits | None = None) -> CoverageResult:
    """Cover ``tree`` like :func:`run_coverage`, timing by iterations of the paper's loop."""
    algo = Algo(algo)
    rule = rule_for(algo)
    return drive(tree, robots, algo, splits,
                 lambda state, splits: iterate(state, rule, splits), "iteration")


def iterate(state: CoverageState, rule: NodeRule, splits: Splits) -> bool:
    """One in-place pass over the occupied nodes, lowest first; False if nobody moved."""
    level, parent = state.level, state.parent
    queue = [(level[v], v) for v in state.at]
    heapq.heapify(queue)
    handled: set[int] = set()
    moved = False
    iteration = state.time + 1
    while queue:
        _, v = heapq.heappop(queue)
        if v in handled or v not in state.at:
            continue
        handled.add(v)
        # Robots that arrived this pass stand on v already, so "leave one" needs no arrival
        # from below (below = 0) and nobody will refill v from above (refilled = False).
        if state.finished(v):
            count = state.at[v] if parent[v] >= 0 else 0
        else:
            count = rule.climb(state, splits, v, 0)
        if count:
            _move_now(state, [Move(v, parent[v], count)], iteration)
            heapq.heappush(queue, (level[parent[v]], parent[v]))
            moved = True
        if v in state.at and state.unexplored[v] > 0:
            down = rule.descend(state, splits, v, state.at[v], False)
            if down:
                _move_now(state, down, iteration)
                moved = True
    state.time = iteration
    return moved


def _move_now(state: CoverageState, moves: list[Move], iteration: int) -> None:
    """Apply moves within the current iteration (visits are stamped with its number)."""
    state.time = iteration - 1
    state.apply(moves)
