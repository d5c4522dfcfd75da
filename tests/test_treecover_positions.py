"""Tree coverage connectivity recomputed from the robots' positions after every step, by a
search over the tree's edges, not by CoverageState.connected (Lemma 4.1 of paper 001)."""

from __future__ import annotations

from collections import Counter

from hypothesis import given, settings
from hypothesis import strategies as st
from treecover_helpers import ALGOS, random_trees

from planner.treecover.sim import initial_state
from planner.treecover.step import decide
from planner.treecover.types import Algo, Tree


def one_component(tree: Tree, occupied: set[int]) -> bool:
    """The occupied nodes, joined by the tree edges between them, form one component."""
    parent = [int(p) for p in tree.parent]
    neighbours: dict[int, set[int]] = {v: set() for v in occupied}
    for v in occupied:
        if parent[v] in occupied:
            neighbours[v].add(parent[v])
            neighbours[parent[v]].add(v)
    start = next(iter(occupied))
    seen, frontier = {start}, [start]
    while frontier:
        for w in neighbours[frontier.pop()] - seen:
            seen.add(w)
            frontier.append(w)
    return seen == occupied


@settings(max_examples=80, deadline=None)
@given(tree=random_trees(), robots=st.integers(1, 30), algo=st.sampled_from(ALGOS))
def test_positions_stay_one_component_along_tree_edges(tree: Tree, robots: int,
                                                       algo: str) -> None:
    splits, state = initial_state(tree, robots, Algo(algo))
    parent = [int(p) for p in tree.parent]
    visited = {0}
    for _ in range(4 * tree.n * (tree.height + 2) + 16):
        if state.done():
            break
        moves = decide(state, Algo(algo), splits)
        if not moves:
            return  # too few robots: a stall the planner reports; nothing to check here
        before = Counter(state.at)
        for move in moves:
            assert parent[move.dst] == move.src or parent[move.src] == move.dst
            before[move.src] -= move.count
            before[move.dst] += move.count
        state.apply(moves)
        after = Counter({v: c for v, c in before.items() if c})
        assert after == Counter(state.at), "positions do not follow the moves"
        assert sum(after.values()) == robots
        assert one_component(tree, set(after)), f"split team at {dict(after)}"
        visited |= set(after)
    assert visited == set(range(tree.n)), "a node was never stood on"
