"""Minimum brick tiling of the free cells (TMSTC* section IV-A).

Removing the border between two adjacent free cells merges them; a horizontal merge and a
vertical merge that touch the same cell would make an L, so they conflict. The conflict graph
is bipartite (horizontal vs vertical merges); a tiling is an independent set and has
S - T bricks (S cells, T merges), so a minimum tiling is a maximum independent set: the
complement of a minimum vertex cover, which König's theorem builds from a maximum matching.

The matching is scipy.sparse.csgraph.maximum_bipartite_matching (Hopcroft-Karp in C): for
Denver_2 (about 3000 merges a side) it takes a few milliseconds. The cover comes from the
alternating breadth-first search of König's proof, also run by csgraph.
"""

from __future__ import annotations

import numpy as np
from scipy.sparse import coo_array
from scipy.sparse.csgraph import (
    breadth_first_order,
    connected_components,
    maximum_bipartite_matching,
)

from planner.tmstc.types import BrickTiling
from planner.types import BoolArray, IntArray


def merge_candidates(cells: BoolArray) -> tuple[IntArray, IntArray]:
    """(row, col) of every possible horizontal merge (cell with its right neighbour) and of
    every vertical merge (cell with the one below), as two (m, 2) arrays."""
    horiz = cells[:, :-1] & cells[:, 1:]
    vert = cells[:-1, :] & cells[1:, :]
    return np.argwhere(horiz), np.argwhere(vert)


def conflict_graph(cells: BoolArray, horiz: IntArray, vert: IntArray) -> coo_array:
    """Biadjacency (horizontal x vertical merges) of merges that share a cell."""
    h, w = cells.shape
    vid = np.full((h + 1, w + 1), -1, dtype=np.int64)
    vid[vert[:, 0], vert[:, 1]] = np.arange(len(vert))
    rows, cols = [], []
    # horizontal merge (r, c)-(r, c+1) meets the vertical merges above and below both cells
    for dr, dc in ((0, 0), (-1, 0), (0, 1), (-1, 1)):
        v = vid[horiz[:, 0] + dr, horiz[:, 1] + dc]
        hit = v >= 0
        rows.append(np.flatnonzero(hit))
        cols.append(v[hit])
    r = np.concatenate(rows)
    c = np.concatenate(cols)
    return coo_array((np.ones(len(r), dtype=np.int8), (r, c)), shape=(len(horiz), len(vert)))


def max_independent_set(graph: coo_array) -> tuple[BoolArray, BoolArray]:
    """A maximum independent set of a bipartite graph, as masks over its two sides (König)."""
    n_left, n_right = graph.shape
    csr = graph.tocsr()
    match_of_left = maximum_bipartite_matching(csr, perm_type="column")
    # Alternating search from the unmatched left vertices: left -> right along any edge,
    # right -> left along the matching. Node ids: left 0..L-1, right L..L+R-1, source L+R.
    left_src, right_dst = csr.nonzero()
    matched = np.flatnonzero(match_of_left >= 0)
    unmatched = np.flatnonzero(match_of_left < 0)
    source = n_left + n_right
    src = np.concatenate([left_src, n_left + match_of_left[matched],
                          np.full(len(unmatched), source)])
    dst = np.concatenate([n_left + right_dst, matched, unmatched])
    walk = coo_array((np.ones(len(src), dtype=np.int8), (src, dst)),
                     shape=(source + 1, source + 1)).tocsr()
    reached = np.zeros(source + 1, dtype=bool)
    reached[breadth_first_order(walk, source, directed=True, return_predecessors=False)] = True
    # minimum cover = (left not reached) + (right reached); the independent set is the rest
    return reached[:n_left], ~reached[n_left:source]


def brick_tiling(cells: BoolArray) -> BrickTiling:
    """A tiling of ``cells`` by the fewest straight bricks."""
    cells = np.asarray(cells, dtype=bool)
    horiz, vert = merge_candidates(cells)
    keep_h, keep_v = max_independent_set(conflict_graph(cells, horiz, vert))
    right = np.zeros(cells.shape, dtype=bool)
    down = np.zeros(cells.shape, dtype=bool)
    right[horiz[keep_h, 0], horiz[keep_h, 1]] = True
    down[vert[keep_v, 0], vert[keep_v, 1]] = True
    brick, count = _label_bricks(cells, right, down)
    return BrickTiling(cells=cells, right=right, down=down, brick=brick, count=count)


def _label_bricks(cells: BoolArray, right: BoolArray, down: BoolArray) -> tuple[IntArray, int]:
    """Brick number of each cell: components of the cells joined by the kept merges."""
    # Each brick is straight, so it is a component of the row-wise or column-wise runs.
    h, w = cells.shape
    flat = np.arange(h * w).reshape(h, w)
    a = np.concatenate([flat[right], flat[down]])
    b = np.concatenate([flat[right] + 1, flat[down] + w])
    graph = coo_array((np.ones(len(a), dtype=np.int8), (a, b)), shape=(h * w, h * w))
    _, labels = connected_components(graph, directed=False)
    labels = labels.reshape(h, w)
    brick = np.full((h, w), -1, dtype=np.int64)
    _, brick_ids = np.unique(labels[cells], return_inverse=True)
    brick[cells] = brick_ids
    return brick, int(brick_ids.max()) + 1 if brick_ids.size else 0
