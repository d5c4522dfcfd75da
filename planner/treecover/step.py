"""One synchronous step of NCOCTA / COCTA, sans I/O: state in, moves out.

Climbs are decided from the lowest height up, as in the paper's Algorithms 1 and 2, so a node
knows how many robots reach it from below; descents are then decided from the top down, so a
node also knows how many reach it from above. "Leave one robot at v" is met by any robot that
ends the step on v: a robot arriving from either side frees the one already there. That is
what lets a chain of h_m robots visit a new node every step (Lemma 4.3's proof: "when a robot
returns to his parent node, the robot that is located at the parent node can move to a
different node"). A node never both sends robots up and receives robots from its parent: a
parent sends only into children with work left for more robots, and a child climbs only when
it has none.
"""

from __future__ import annotations

from typing import Protocol

from planner.treecover import cocta, ncocta
from planner.treecover.state import CoverageState
from planner.treecover.types import Algo, Move, Splits


class NodeRule(Protocol):
    """An algorithm's per-node rule, applied to occupied nodes that are not finished."""

    def climb(self, state: CoverageState, splits: Splits, v: int, below: int) -> int: ...

    def descend(self, state: CoverageState, splits: Splits, v: int, staying: int,
                refilled: bool) -> list[Move]: ...


_RULES: dict[Algo, NodeRule] = {Algo.NCOCTA: ncocta.RULE, Algo.COCTA: cocta.RULE}


def rule_for(algo: Algo) -> NodeRule:
    """The node rule of ``algo`` (shared by the step driver and the loop-iteration driver)."""
    return _RULES[algo]


def decide(state: CoverageState, algo: Algo, splits: Splits) -> list[Move]:
    """The moves every robot makes in the next step."""
    return decide_with(state, rule_for(algo), splits)


def decide_with(state: CoverageState, rule: NodeRule, splits: Splits) -> list[Move]:
    """:func:`decide` for any node rule (alternative readings are measured with it)."""
    parent, at = state.parent, state.at
    order = sorted(at, key=state.level.__getitem__)
    moves: list[Move] = []
    below: dict[int, int] = {}
    climbed: dict[int, int] = {}
    for v in order:
        if state.finished(v):
            # nothing left below v: everyone climbs (the root's team simply stops)
            count = at[v] if parent[v] >= 0 else 0
        else:
            count = rule.climb(state, splits, v, below.get(v, 0))
        if count:
            moves.append(Move(v, parent[v], count))
            below[parent[v]] = below.get(parent[v], 0) + count
            climbed[v] = count
    above: dict[int, int] = {}
    for v in reversed(order):
        if state.unexplored[v] == 0:
            continue
        staying = at[v] - climbed.get(v, 0)
        refilled = below.get(v, 0) + above.get(v, 0) > 0
        for move in rule.descend(state, splits, v, staying, refilled):
            moves.append(move)
            above[move.dst] = above.get(move.dst, 0) + move.count
    return moves
