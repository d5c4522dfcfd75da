"""Greedy merging of bricks into a spanning tree by turn cost (TMSTC* Alg. 1, eq. 5-6).

Edges between bricks sit in a binary heap keyed by the turns they add; an edge's cost goes
stale when a neighbouring edge is taken, so a popped edge is re-costed and taken only if its
cost did not change (else pushed back), as in the paper. Union-find over brick ids rejects
edges that would close a cycle. Ties are broken by a seeded random key, so different seeds
give different trees of (often) different quality; :func:`merge_bricks` takes one seed.
"""

from __future__ import annotations

import heapq

import numpy as np

from planner.tmstc.tiling import merge_candidates
from planner.tmstc.turns import DOWN, LEFT, RIGHT, TURNS, UP, side_masks
from planner.tmstc.types import BrickTiling
from planner.types import SpanningTree


def _find(parent: list[int], x: int) -> int:
    while parent[x] != x:
        parent[x] = parent[parent[x]]
        x = parent[x]
    return x


def merge_bricks(tiling: BrickTiling, *, seed: int = 0) -> SpanningTree:
    """Join the bricks of ``tiling`` into one spanning tree, cheapest turn cost first.

    The tiling's cells must be 4-connected (one component), else ValueError.
    """
    cells = tiling.cells
    _h, w = cells.shape
    mask = side_masks(cells, tiling.right, tiling.down).ravel().tolist()
    brick = tiling.brick.ravel().tolist()
    horiz, vert = merge_candidates(cells)
    horiz = horiz[~tiling.right[horiz[:, 0], horiz[:, 1]]]
    vert = vert[~tiling.down[vert[:, 0], vert[:, 1]]]
    a = np.concatenate([horiz[:, 0] * w + horiz[:, 1], vert[:, 0] * w + vert[:, 1]])
    b = np.concatenate([a[:len(horiz)] + 1, a[len(horiz):] + w])
    bit_a = np.concatenate([np.full(len(horiz), RIGHT), np.full(len(vert), DOWN)])
    bit_b = np.concatenate([np.full(len(horiz), LEFT), np.full(len(vert), UP)])
    masks = np.asarray(mask)
    cost = (TURNS[masks[a] | bit_a] + TURNS[masks[b] | bit_b]
            - TURNS[masks[a]] - TURNS[masks[b]])
    tie = np.random.default_rng(seed).permutation(len(a))
    heap = list(zip(cost.tolist(), tie.tolist(), range(len(a)), strict=True))
    heapq.heapify(heap)
    ends = list(zip(a.tolist(), b.tolist(), bit_a.tolist(), bit_b.tolist(), strict=True))
    turns = TURNS.tolist()
    parent = list(range(tiling.count))
    right = tiling.right.copy()
    down = tiling.down.copy()
    joins = tiling.count - 1
    while heap and joins:
        stored, key, e = heapq.heappop(heap)
        u, v, bu, bv = ends[e]
        ru, rv = _find(parent, brick[u]), _find(parent, brick[v])
        if ru == rv:
            continue
        now = (turns[mask[u] | bu] + turns[mask[v] | bv] - turns[mask[u]] - turns[mask[v]])
        if now != stored:
            heapq.heappush(heap, (now, key, e))
            continue
        parent[ru] = rv
        mask[u] |= bu
        mask[v] |= bv
        if bu == RIGHT:
            right[u // w, u % w] = True
        else:
            down[u // w, u % w] = True
        joins -= 1
    if joins:
        raise ValueError("the cells are not connected: the bricks cannot form one tree")
    return SpanningTree(cells=cells, right=right, down=down)
