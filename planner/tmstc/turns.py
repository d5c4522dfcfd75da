"""Turns of the STC cycle counted per tree vertex (TMSTC* eq. 5).

The circumnavigation turns only inside cells, and how often it turns inside a cell depends
only on which of the cell's four sides carry tree edges: 0 for a straight pass, 2 for a leaf,
an L or a T, 4 for a cross or an isolated cell. So the cycle's turn count is the sum over cells,
and adding or removing one edge changes it only at the edge's two cells (eq. 6).
"""

from __future__ import annotations

import numpy as np

from planner.types import BoolArray, IntArray, SpanningTree

UP, DOWN, LEFT, RIGHT = 1, 2, 4, 8


def _turns_of_mask(mask: int) -> int:
    degree = bin(mask).count("1")
    if degree == 0 or degree == 4:
        return 4
    if degree == 2:
        return 0 if mask in (UP | DOWN, LEFT | RIGHT) else 2
    return 2


TURNS = np.array([_turns_of_mask(m) for m in range(16)], dtype=np.int64)


def side_masks(cells: BoolArray, right: BoolArray, down: BoolArray) -> IntArray:
    """Per cell, which sides carry an edge (bit flags UP, DOWN, LEFT, RIGHT)."""
    mask = np.zeros(cells.shape, dtype=np.int64)
    mask[right] |= RIGHT
    mask[:, 1:][right[:, :-1]] |= LEFT
    mask[down] |= DOWN
    mask[1:, :][down[:-1, :]] |= UP
    return mask


def tree_turns(tree: SpanningTree) -> int:
    """Quarter turns of the closed STC cycle around ``tree`` (sum of eq. 5 over cells)."""
    mask = side_masks(tree.cells, tree.right, tree.down)
    return int(TURNS[mask[tree.cells]].sum())
