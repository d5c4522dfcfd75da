"""Local improvement of a spanning tree's turn count by edge swaps (our addition to TMSTC*).

Adding a non-tree edge closes one cycle in the tree; dropping any edge of that cycle gives
another spanning tree. By eq. 5-6 the turn change only involves the (up to four) cells at the
two edges' ends, so each candidate swap is priced in O(1) and the best drop on the cycle is
found by walking the tree path between the added edge's cells. A swap is made only when it
strictly lowers the turn count, so the pass terminates and never makes a tree worse.
Dropping an edge lowers a cell's turns by at most 2, so added edges costing 4 or more turns
are skipped without walking.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from planner.tmstc.turns import DOWN, LEFT, RIGHT, TURNS, UP, side_masks
from planner.types import SpanningTree

_OPPOSITE = {UP: DOWN, DOWN: UP, LEFT: RIGHT, RIGHT: LEFT}


class _Tree:
    """Flat-index tree with side masks, parent pointers and depths (private)."""

    def __init__(self, tree: SpanningTree) -> None:
        self.cells = tree.cells
        self.w = int(tree.cells.shape[1])
        self.mask = side_masks(tree.cells, tree.right, tree.down).ravel().tolist()
        self.turns = TURNS.tolist()
        self.root = int(np.flatnonzero(tree.cells.ravel())[0])
        self.parent: list[int] = []
        self.depth: list[int] = []
        self.reroot()

    def step(self, x: int, bit: int) -> int:
        return x + {UP: -self.w, DOWN: self.w, LEFT: -1, RIGHT: 1}[bit]

    def reroot(self) -> None:
        size = len(self.mask)
        self.parent = [-1] * size
        self.depth = [0] * size
        queue = deque([self.root])
        self.parent[self.root] = self.root
        while queue:
            x = queue.popleft()
            m = self.mask[x]
            for bit in (UP, DOWN, LEFT, RIGHT):
                if m & bit:
                    y = self.step(x, bit)
                    if self.parent[y] < 0:
                        self.parent[y] = x
                        self.depth[y] = self.depth[x] + 1
                        queue.append(y)

    def bit_towards(self, x: int, y: int) -> int:
        d = y - x
        return UP if d == -self.w else DOWN if d == self.w else LEFT if d == -1 else RIGHT

    def delta(self, changes: dict[int, int]) -> int:
        """Turn change if each cell's mask were replaced as given."""
        t = self.turns
        return sum(t[new] - t[self.mask[x]] for x, new in changes.items())

    def best_drop(self, u: int, v: int, bu: int, bv: int) -> tuple[int, int, int]:
        """(turn change, x, y) of adding u-v and dropping the best edge x-y on the cycle."""
        added = {u: self.mask[u] | bu, v: self.mask[v] | bv}
        best = (10**9, -1, -1)
        a, b = u, v
        while a != b:
            if self.depth[a] < self.depth[b]:
                a, b = b, a
            p = self.parent[a]
            ba = self.bit_towards(a, p)
            change = dict(added)
            change[a] = change.get(a, self.mask[a]) & ~ba
            change[p] = change.get(p, self.mask[p]) & ~_OPPOSITE[ba]
            total = self.delta(change)
            if total < best[0]:
                best = (total, a, p)
            a = p
        return best

    def swap(self, u: int, v: int, x: int, y: int) -> None:
        bu = self.bit_towards(u, v)
        self.mask[u] |= bu
        self.mask[v] |= _OPPOSITE[bu]
        bx = self.bit_towards(x, y)
        self.mask[x] &= ~bx
        self.mask[y] &= ~_OPPOSITE[bx]
        self.reroot()

    def to_tree(self) -> SpanningTree:
        mask = np.asarray(self.mask).reshape(self.cells.shape)
        return SpanningTree(cells=self.cells, right=(mask & RIGHT) > 0, down=(mask & DOWN) > 0)


def improve_turns(tree: SpanningTree, *, max_passes: int = 8) -> SpanningTree:
    """Edge swaps that each strictly lower the cycle's turns, until none is left."""
    state = _Tree(tree)
    cells = tree.cells
    w = state.w
    horiz = np.argwhere(cells[:, :-1] & cells[:, 1:])
    pairs = [(int(r) * w + int(c), RIGHT) for r, c in horiz]
    vert = np.argwhere(cells[:-1, :] & cells[1:, :])
    pairs += [(int(r) * w + int(c), DOWN) for r, c in vert]
    for _ in range(max_passes):
        improved = False
        for u, bit in pairs:
            if state.mask[u] & bit:
                continue
            v = state.step(u, bit)
            bv = _OPPOSITE[bit]
            if state.delta({u: state.mask[u] | bit, v: state.mask[v] | bv}) >= 4:
                continue
            total, x, y = state.best_drop(u, v, bit, bv)
            if x >= 0 and total < 0:
                state.swap(u, v, x, y)
                improved = True
        if not improved:
            break
    return state.to_tree()
