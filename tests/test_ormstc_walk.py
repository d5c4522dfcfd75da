"""The online STC walk geometry against the repository's offline STC cycle (planner.cycle)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from oracles import bfs_tree, random_cells

from planner.cycle import stc_cycle
from planner.ormstc.walk import (
    arrival_side,
    cell_of,
    initial_arrival,
    neighbour,
    predecessor,
    side_of,
    side_towards,
    sub_facing,
    successor,
)


def _edge_test(tree_right: np.ndarray, tree_down: np.ndarray):  # type: ignore[no-untyped-def]
    h, w = tree_right.shape

    def has_edge(cell: tuple[int, int], side: int) -> bool:
        other = neighbour(cell, side)
        if not (0 <= other[0] < h and 0 <= other[1] < w and 0 <= cell[0] < h
                and 0 <= cell[1] < w):
            return False
        (r0, c0), (r1, _c1) = sorted((cell, other))
        return bool(tree_right[r0, c0]) if r0 == r1 else bool(tree_down[r0, c0])

    return has_edge


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 10_000), h=st.integers(1, 7), w=st.integers(1, 7))
def test_successor_walk_is_the_stc_cycle(seed: int, h: int, w: int) -> None:
    cells = random_cells(np.random.default_rng(seed), (h, w), 0.3)
    tree = bfs_tree(cells)
    cycle = stc_cycle(tree)
    has_edge = _edge_test(tree.right, tree.down)
    for i in range(cycle.n):
        here, ahead = cycle.at(i), cycle.at(i + 1)
        assert successor(here, has_edge) == ahead
        assert predecessor(ahead, has_edge) == here


def test_sides_and_facing_sub_cells_agree() -> None:
    for cell in [(0, 0), (3, 5), (-2, 7)]:
        for side in range(4):
            sub = sub_facing(cell, side)
            assert cell_of(sub) == cell
            assert side_of(sub) == side
            assert side_towards(cell, neighbour(cell, side)) == side


def test_initial_w_is_the_side_walked_in_from() -> None:
    # Fig. 1: entering a cell over side W lands exactly on the start sub-cell, so the walk
    # from a cell with an edge to W arrives at the start (checked on a two-cell tree).
    for start in [(4, 4), (5, 4), (5, 5), (4, 5)]:
        w_cell = initial_arrival(start)
        cell = cell_of(start)
        side = side_towards(cell, w_cell)
        assert side == arrival_side(start)
        edges = {(cell, side), (w_cell, (side + 2) % 4)}

        def has_edge(c: tuple[int, int], s: int,
                     edges: set[tuple[tuple[int, int], int]] = edges) -> bool:
            return (c, s) in edges

        sub = sub_facing(cell, side)
        walked = successor(sub, has_edge)
        for _ in range(8):
            if cell_of(walked) == cell:
                break
            walked = successor(walked, has_edge)
        assert walked == start
