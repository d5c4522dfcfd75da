"""The STC cycle: circumnavigate a spanning tree counter-clockwise through every sub-cell.

Each sub-cell has exactly one successor. Inside a cell the walk goes round counter-clockwise
(top-left -> bottom-left -> bottom-right -> top-right -> top-left, rows growing downwards);
where a tree edge crosses the side a sub-cell would walk along, the walk steps over the edge
into the neighbouring cell instead, so the tree is always on the walker's left. For a spanning
tree the successor map is one single cycle (Gabriely & Rimon); the successors are computed
with numpy for the whole grid at once and the cycle is then read off by following them.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from planner.types import Cycle, IntArray, SpanningTree, SubCell

if TYPE_CHECKING:
    from scipy.sparse import csr_matrix


def successor_map(tree: SpanningTree) -> IntArray:
    """Flat index of the successor of every sub-cell of the tree's cells (-1 elsewhere)."""
    ch, cw = tree.cells.shape
    h, w = 2 * ch, 2 * cw
    nxt = np.full((h, w), -1, dtype=np.int64)
    rows = np.arange(ch)[:, None] * 2
    cols = np.arange(cw)[None, :] * 2

    def flat(r: IntArray, c: IntArray) -> IntArray:
        return r * w + c

    left = np.zeros((ch, cw), dtype=bool)
    left[:, 1:] = tree.right[:, :-1]
    up = np.zeros((ch, cw), dtype=bool)
    up[1:, :] = tree.down[:-1, :]
    r0 = np.broadcast_to(rows, (ch, cw))
    c0 = np.broadcast_to(cols, (ch, cw))
    # top-left walks down the left side, or crosses left into the neighbour's top-right
    tl = np.where(left, flat(r0, c0 - 1), flat(r0 + 1, c0))
    # bottom-left walks right along the bottom, or crosses down into the neighbour's top-left
    bl = np.where(tree.down, flat(r0 + 2, c0), flat(r0 + 1, c0 + 1))
    # bottom-right walks up the right side, or crosses right into the neighbour's bottom-left
    br = np.where(tree.right, flat(r0 + 1, c0 + 2), flat(r0, c0 + 1))
    # top-right walks left along the top, or crosses up into the neighbour's bottom-right
    tr = np.where(up, flat(r0 - 1, c0 + 1), flat(r0, c0))
    cells = tree.cells
    nxt[0::2, 0::2] = np.where(cells, tl, -1)
    nxt[1::2, 0::2] = np.where(cells, bl, -1)
    nxt[1::2, 1::2] = np.where(cells, br, -1)
    nxt[0::2, 1::2] = np.where(cells, tr, -1)
    return nxt.ravel()


def stc_cycle(tree: SpanningTree, start: SubCell | None = None) -> Cycle:
    """The counter-clockwise circumnavigation of ``tree``, beginning at ``start``.

    ``start`` defaults to the top-left sub-cell of the first tree cell in row-major order.
    Raises ValueError when the successor map is not one cycle through all sub-cells (the
    tree is not a spanning tree of its cells).
    """
    ch, cw = tree.cells.shape
    w = 2 * cw
    nxt = successor_map(tree)
    n = 4 * tree.cell_count
    if n == 0:
        raise ValueError("the tree has no cells")
    if start is None:
        first = int(np.flatnonzero(tree.cells.ravel())[0])
        start = (2 * (first // cw), 2 * (first % cw))
    at = start[0] * w + start[1]
    if not (0 <= at < nxt.size) or nxt[at] < 0:
        raise ValueError(f"start {start} is not a sub-cell of the tree's cells")
    order = np.empty(n, dtype=np.int64)
    nxt_list = nxt.tolist()  # plain ints: following 10^5 pointers is 5x faster than numpy
    for i in range(n):
        order[i] = at
        at = nxt_list[at]
        if at < 0:
            raise ValueError("the successor walk left the tree: the tree is not spanning")
    if at != order[0]:
        raise ValueError("the walk did not close after n sub-cells: the tree is not one tree")
    index = np.full(2 * ch * w, -1, dtype=np.int64)
    index[order] = np.arange(n)
    if np.count_nonzero(index >= 0) != n:
        raise ValueError("the walk visited a sub-cell twice: the tree has a cycle")
    path = np.stack([order // w, order % w], axis=1)
    return Cycle(path=path, index=index.reshape(2 * ch, w))


def order_robots(cycle: Cycle, starts: list[SubCell] | tuple[SubCell, ...]) -> list[int]:
    """Robot ids sorted by their start's position along the cycle (counter-clockwise)."""
    positions = [cycle.position(s) for s in starts]
    missing = [robot for robot, p in enumerate(positions) if p < 0]
    if missing:
        raise ValueError(f"robots {missing} do not start on the cycle")
    return sorted(range(len(starts)), key=lambda robot: positions[robot])


def cycle_graph(cycle: Cycle) -> csr_matrix:
    """The 4-adjacency of the cycle's sub-cells, nodes = cycle indices, each pair once (for
    scipy.sparse.csgraph with ``directed=False``): shortest walks between places."""
    # Imported here: the agents import this module, and only their re-plans need scipy.
    from scipy.sparse import csr_matrix

    index = cycle.index
    pairs = [(index[:-1, :], index[1:, :]), (index[:, :-1], index[:, 1:])]
    src = np.concatenate([a[(a >= 0) & (b >= 0)] for a, b in pairs])
    dst = np.concatenate([b[(a >= 0) & (b >= 0)] for a, b in pairs])
    return csr_matrix((np.ones(src.size, dtype=np.int8), (src, dst)), shape=(cycle.n, cycle.n))
