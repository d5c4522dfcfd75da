"""NCOCTA's rule for one occupied node that is not finished (paper 001, Algorithm 1).

Above h_1 the whole team walks together; at a split height it leaves one robot and splits the
rest evenly among the unfinished children; below, it leaves a trail of one robot per node; a
split node whose subtree is explored waits until every robot is back, then the team moves on.
"""

from __future__ import annotations

from planner.treecover.rules import climb_leaving_one, moves_down, split_evenly, unfinished_children
from planner.treecover.state import CoverageState
from planner.treecover.types import Move, Splits


class NcoctaRule:
    """Algorithm 1 as a node rule for :func:`planner.treecover.step.decide`."""

    def climb(self, state: CoverageState, splits: Splits, v: int, below: int) -> int:
        if state.unexplored[v] or state.parent[v] < 0 or state.level[v] in splits.heights:
            return 0  # work left below, or the root, or a split node waiting for its team
        if any(state.unexplored[u] for u in state.children[v]):
            return 0
        return climb_leaving_one(state, v, below)

    def descend(self, state: CoverageState, splits: Splits, v: int, staying: int,
                refilled: bool) -> list[Move]:
        kids = unfinished_children(state, v)
        if not kids or staying <= 0:
            return []
        if state.level[v] > splits.h1 and staying == state.robots:
            return [Move(v, kids[0], staying)]  # the whole team walks together
        avail = staying if refilled else staying - 1
        if avail <= 0:
            return []
        if state.level[v] in splits.heights:
            return moves_down(v, kids, split_evenly(avail, [state.sub[u] for u in kids], None))
        return [Move(v, kids[0], avail)]


RULE = NcoctaRule()
