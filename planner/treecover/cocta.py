"""COCTA's rule for one occupied node that is not finished (paper 001, Algorithm 2): NCOCTA
plus dripping.

A child gets no more robots than it can use (:meth:`CoverageState.useful`: its nodes that are
not finished, section 4.3); the rest go to other children, and robots a subtree cannot use
drip to the parent, which hands them to another subtree. An explored subtree does not wait for
its team: robots climb at once, leaving one behind per node to keep the team connected.
"""

from __future__ import annotations

from planner.treecover.rules import (
    climb_leaving_one,
    fill_in_order,
    moves_down,
    split_evenly,
    unfinished_children,
)
from planner.treecover.state import CoverageState
from planner.treecover.types import Move, Splits


class CoctaRule:
    """Algorithm 2 as a node rule for :func:`planner.treecover.step.decide`."""

    def climb(self, state: CoverageState, splits: Splits, v: int, below: int) -> int:
        if state.parent[v] < 0:
            return 0
        if state.level[v] >= splits.h1:
            return 0  # the team regroups at h_1 and walks on together, as in NCOCTA
        if state.unexplored[v] == 0:
            return climb_leaving_one(state, v, below)
        surplus = state.sub[v] - state.useful(v)
        if surplus <= 0:
            return 0
        return max(0, min(surplus, climb_leaving_one(state, v, below)))

    def descend(self, state: CoverageState, splits: Splits, v: int, staying: int,
                refilled: bool) -> list[Move]:
        kids = unfinished_children(state, v)
        if not kids or staying <= 0:
            return []
        if state.level[v] > splits.h1 and staying == state.robots:
            return [Move(v, kids[0], staying)]  # above h_1 the whole team walks together
        caps = [max(0, state.useful(u) - state.sub[u]) for u in kids]
        avail = staying if refilled else staying - 1
        if avail <= 0:
            return []
        if state.level[v] in splits.heights:
            return moves_down(v, kids, split_evenly(avail, [state.sub[u] for u in kids], caps))
        return moves_down(v, kids, fill_in_order(avail, caps))


RULE = CoctaRule()
