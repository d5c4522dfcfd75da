"""Trail repair after a robot dies: refill the node it leaves empty, or gather the team.

A dead robot that was the only one on a node between other robots leaves a *hole*: an empty
node with robots on two or more of its sides (its parent's side and its child subtrees), so
the occupied nodes no longer induce one connected subtree (Lemma 4.1). :func:`refill_moves`
closes every hole in one step, before anything else moves: a spare robot of the parent's node
walks down, or else the chain below is pulled up one edge (each robot on the chain climbs;
the pull stops at the first node that keeps a robot, or at the end of the chain), which is
"leave one" again. :func:`gather_moves` walks every robot one edge towards the top occupied
node; the occupied set stays closed upwards, hence connected, while the team regroups (the
fallback when the survivors are too few for the splits, docs/treecover.md).
"""

from __future__ import annotations

from planner.treecover.state import CoverageState
from planner.treecover.types import Move


def holes(state: CoverageState) -> list[int]:
    """Empty nodes on the paths between occupied nodes, top first."""
    parent, depth = state.parent, state.tree.depth
    occupied = set(state.at)
    if len(occupied) < 2:
        return []
    span: dict[int, int] = {}  # node -> occupied nodes whose path to the top passes it
    for x in occupied:
        v = x
        while v >= 0:
            span[v] = span.get(v, 0) + 1
            v = parent[v]
    everyone = len(occupied)
    # the spanning subtree: nodes below the deepest node that every path passes through
    top = max((v for v, count in span.items() if count == everyone), key=lambda v: depth[v])
    inside = [v for v in span if v == top or _below(parent, v, top)]
    return sorted((v for v in inside if v not in occupied), key=lambda v: int(depth[v]))


def _below(parent: list[int], v: int, top: int) -> bool:
    while v >= 0:
        if v == top:
            return True
        v = parent[v]
    return False


def refill_moves(state: CoverageState) -> list[Move]:
    """One step that puts a robot on every hole (empty if there is none)."""
    gaps = holes(state)
    if not gaps:
        return []
    occupied_below = _occupied_below(state)
    leaving: dict[int, int] = {}
    moves: list[Move] = []
    for hole in gaps:
        if _spare(state, leaving, state.parent[hole]):
            src = state.parent[hole]
            leaving[src] = leaving.get(src, 0) + 1
            moves.append(Move(src, hole, 1))
            continue
        _pull_chain(state, hole, occupied_below, leaving, moves)
    return moves


def _spare(state: CoverageState, leaving: dict[int, int], v: int) -> bool:
    """Node ``v`` has a robot it can send away and still keep one."""
    return v >= 0 and state.at.get(v, 0) - leaving.get(v, 0) >= 2


def _occupied_below(state: CoverageState) -> set[int]:
    """Nodes with an occupied node strictly below them."""
    marked: set[int] = set()
    for x in state.at:
        v = state.parent[x]
        while v >= 0 and v not in marked:
            marked.add(v)
            v = state.parent[v]
    return marked


def _pull_chain(state: CoverageState, hole: int, occupied_below: set[int],
                leaving: dict[int, int], moves: list[Move]) -> None:
    """Every robot on one chain below ``hole`` climbs one edge, down to a node that keeps a
    robot or has nothing below it. The chain follows the child holding most robots."""
    target = hole
    while True:
        kids = [u for u in state.children[target]
                if state.at.get(u, 0) - leaving.get(u, 0) > 0 or u in occupied_below]
        if not kids:
            return
        child = max(kids, key=lambda u: (state.sub[u], -u))
        have = state.at.get(child, 0) - leaving.get(child, 0)
        if have < 1:
            return  # a second hole right below: cannot be closed in the same step
        leaving[child] = leaving.get(child, 0) + 1
        moves.append(Move(child, target, 1))
        if have >= 2 or child not in occupied_below:
            return
        target = child


def gather_moves(state: CoverageState) -> list[Move]:
    """Every robot not on the top occupied node climbs one edge (empty once regrouped)."""
    parent = state.parent
    top = min(state.at, key=lambda v: int(state.tree.depth[v]))
    return [Move(v, parent[v], count) for v, count in state.at.items() if v != top]
