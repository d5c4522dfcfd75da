"""Spanning trees over the free coarse cells: DFS, BFS, uniform random (Wilson) and turn-averse MST.

All builders work on flat cell indices (``r * width + c``) and plain Python lists: for the
pointer-chasing walks that is several times faster than indexing numpy arrays element by element.
Every builder is deterministic for a given seed.
"""

from __future__ import annotations

import itertools
import random
from collections import deque
from collections.abc import Iterable, Sequence

import numpy as np

from planner.errors import EmptyMapError, TreeError
from planner.grid import label_components
from planner.types import BoolArray, Cell, IntArray, SpanningTree

TREE_KINDS = ("dfs", "bfs", "random", "kruskal")
# Trees from the papers' own constructions (planner.createtree, planner.tmstc); "createtree"
# grows from the robots' start cells, so build_tree needs ``starts`` for it.
PAPER_TREE_KINDS = ("createtree", "tmstc")
ALL_TREE_KINDS = TREE_KINDS + PAPER_TREE_KINDS

# Fixed neighbour order used when seed is None: north, east, south, west (as (dr, dc)).
_DIRECTIONS: tuple[tuple[int, int], ...] = ((-1, 0), (0, 1), (1, 0), (0, -1))
# Kruskal weights: a vertical edge costs twice a horizontal one, so the MST links rows by as few
# vertical edges as possible; the jitter (< 0.5) only breaks ties and never flips that preference.
_HORIZONTAL_WEIGHT = 1.0
_VERTICAL_WEIGHT = 2.0
_JITTER = 0.5
_SMALL_MST = 256  # edges up to which a seeded kruskal tree is found without scipy


def build_tree(cells: BoolArray, kind: str = "dfs", *, seed: int | None = 0,
               root: Cell | None = None, starts: Sequence[Cell] | None = None) -> SpanningTree:
    """A spanning tree of the free cells ``cells`` (one 4-connected component).

    ``kind`` is one of TREE_KINDS. ``seed`` shuffles the neighbour order of dfs/bfs, drives the
    random walks of Wilson's algorithm and the tie-breaking jitter of kruskal; ``seed=None``
    means no randomisation: dfs/bfs try neighbours north, east, south, west; kruskal uses its
    plain weights (ties broken by scipy's edge order); random uses seed 0. ``root`` (default:
    the first free cell in row-major order) is where dfs/bfs start and Wilson's tree is rooted.
    ``starts`` (the robots' start cells) is needed by "createtree" (paper 000, Create Tree);
    "tmstc" is TMSTC*'s turn-minimising tree (paper 002).
    """
    cells = _validate_cells(cells)
    if kind not in ALL_TREE_KINDS:
        raise TreeError(
            f"unknown tree kind {kind!r}; choose one of {', '.join(ALL_TREE_KINDS)}")
    if kind in PAPER_TREE_KINDS:
        return _paper_tree(cells, kind, 0 if seed is None else seed, starts)
    root_flat = _root_index(cells, root)
    if kind == "kruskal":
        return _kruskal(cells, seed)
    neighbours = _neighbour_lists(cells)
    parent: list[int]
    if kind == "random":
        parent = _wilson(neighbours, root_flat, 0 if seed is None else seed)
    else:
        rng = None if seed is None else random.Random(seed)
        walk = _dfs if kind == "dfs" else _bfs
        parent = walk(neighbours, root_flat, rng)
    return _tree_from_parents(cells, parent)


def _paper_tree(cells: BoolArray, kind: str, seed: int,
                starts: Sequence[Cell] | None) -> SpanningTree:
    # imported here: both packages build on this module
    if kind == "tmstc":
        from planner.tmstc import tmstc_tree

        return tmstc_tree(cells, seed=seed)
    if not starts:
        raise TreeError("the createtree kind grows one subtree per robot: it needs the starts")
    from planner.createtree import create_tree

    return create_tree(cells, list(starts), seed=seed)


def tree_from_edges(cells: BoolArray, edges: Iterable[tuple[Cell, Cell]]) -> SpanningTree:
    """A SpanningTree from explicit edges, each between two 4-adjacent cells of ``cells``.

    Only the edges are validated (in range, free, adjacent, not repeated); whether they span
    the cells is for planner.invariants.check_tree to say.
    """
    cells = np.asarray(cells, dtype=bool)
    if cells.ndim != 2:
        raise TreeError("cells must be a 2-D bool array")
    h, w = cells.shape
    right = np.zeros((h, w), dtype=bool)
    down = np.zeros((h, w), dtype=bool)
    for a, b in edges:
        (r1, c1), (r2, c2) = sorted((_cell(a), _cell(b)))
        for r, c in ((r1, c1), (r2, c2)):
            if not (0 <= r < h and 0 <= c < w) or not cells[r, c]:
                raise TreeError(f"edge {a}-{b}: cell ({r}, {c}) is not a free cell of the grid")
        if r1 == r2 and c2 == c1 + 1:
            target = right
        elif c1 == c2 and r2 == r1 + 1:
            target = down
        else:
            raise TreeError(f"edge {a}-{b} does not join two 4-adjacent cells")
        if target[r1, c1]:
            raise TreeError(f"edge {a}-{b} is given twice")
        target[r1, c1] = True
    return SpanningTree(cells=cells.copy(), right=right, down=down)


def _cell(value: Cell) -> Cell:
    return (int(value[0]), int(value[1]))


def _validate_cells(cells: BoolArray) -> BoolArray:
    cells = np.asarray(cells, dtype=bool)
    if cells.ndim != 2:
        raise TreeError("cells must be a 2-D bool array")
    if not cells.any():
        raise EmptyMapError("no free cell to build a spanning tree over")
    _, count = label_components(cells)
    if count > 1:
        raise TreeError(
            f"the free cells form {count} disconnected components; a spanning tree needs one "
            "(restrict the cells to one component, e.g. the robots' work-area)")
    return cells


def _root_index(cells: BoolArray, root: Cell | None) -> int:
    h, w = cells.shape
    if root is None:
        return int(np.flatnonzero(cells.ravel())[0])
    r, c = _cell(root)
    if not (0 <= r < h and 0 <= c < w) or not cells[r, c]:
        raise TreeError(f"tree root ({r}, {c}) is not a free cell of the {h} x {w} grid")
    return r * w + c


def _neighbour_lists(cells: BoolArray) -> list[list[int]]:
    """Flat indices of each cell's free 4-neighbours, in N/E/S/W order (empty for blocked)."""
    h, w = cells.shape
    free = cells.ravel().tolist()
    out: list[list[int]] = [[] for _ in range(h * w)]
    for u in np.flatnonzero(cells.ravel()).tolist():
        r, c = divmod(u, w)
        for dr, dc in _DIRECTIONS:
            rr, cc = r + dr, c + dc
            if 0 <= rr < h and 0 <= cc < w and free[rr * w + cc]:
                out[u].append(rr * w + cc)
    return out


def _ordered(nbrs: list[int], rng: random.Random | None) -> list[int]:
    if rng is None:
        return nbrs
    shuffled = nbrs.copy()
    rng.shuffle(shuffled)
    return shuffled


def _dfs(neighbours: list[list[int]], root: int, rng: random.Random | None) -> list[int]:
    """Parent of each cell in a depth-first tree (iterative, so 10^5 cells do not overflow)."""
    parent = [-1] * len(neighbours)
    seen = [False] * len(neighbours)
    seen[root] = True
    stack = [(root, iter(_ordered(neighbours[root], rng)))]
    while stack:
        u, pending = stack[-1]
        for v in pending:
            if not seen[v]:
                seen[v] = True
                parent[v] = u
                stack.append((v, iter(_ordered(neighbours[v], rng))))
                break
        else:
            stack.pop()
    return parent


def _bfs(neighbours: list[list[int]], root: int, rng: random.Random | None) -> list[int]:
    """Parent of each cell in a breadth-first tree."""
    parent = [-1] * len(neighbours)
    seen = [False] * len(neighbours)
    seen[root] = True
    queue = deque([root])
    while queue:
        u = queue.popleft()
        for v in _ordered(neighbours[u], rng):
            if not seen[v]:
                seen[v] = True
                parent[v] = u
                queue.append(v)
    return parent


def _wilson(neighbours: list[list[int]], root: int, seed: int) -> list[int]:
    """Parent of each cell in a uniformly random spanning tree (Wilson 1996).

    Loop erasure is implicit: the walk records only the last exit from each cell, so retracing
    from the walk's start follows the loop-erased path. Random choices come in numpy batches of
    integers in [0, 12): 12 is divisible by every degree 1..4, so ``r % degree`` is uniform.
    """
    rng = np.random.default_rng(seed)
    # Batches scale with the grid so tiny grids do not pay for 65536 draws per tree.
    batch_size = max(256, min(1 << 16, 8 * len(neighbours)))
    batch: list[int] = []
    at = 0
    in_tree = [False] * len(neighbours)
    in_tree[root] = True
    parent = [-1] * len(neighbours)
    nxt = [-1] * len(neighbours)
    for start in range(len(neighbours)):
        if in_tree[start] or not neighbours[start]:
            continue
        u = start
        while not in_tree[u]:
            if at == len(batch):
                batch = rng.integers(0, 12, size=batch_size).tolist()
                at = 0
            nbrs = neighbours[u]
            v = nbrs[batch[at] % len(nbrs)]
            at += 1
            nxt[u] = v
            u = v
        u = start
        while not in_tree[u]:
            in_tree[u] = True
            parent[u] = nxt[u]
            u = nxt[u]
    return parent


def _kruskal(cells: BoolArray, seed: int | None) -> SpanningTree:
    """Minimum spanning tree with horizontal edges cheaper than vertical ones (fewer turns)."""
    # Imported here, not at the top: scipy.sparse.csgraph is 31 MB (24 MB more per agent
    # process, whose budget is 80 MB), and of the offline agents' tree kinds only this one
    # needs it.
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import minimum_spanning_tree

    h, w = cells.shape
    idx = np.arange(h * w).reshape(h, w)
    horizontal = cells[:, :-1] & cells[:, 1:]
    vertical = cells[:-1, :] & cells[1:, :]
    src = np.concatenate([idx[:, :-1][horizontal], idx[:-1, :][vertical]])
    dst = np.concatenate([idx[:, 1:][horizontal], idx[1:, :][vertical]])
    weight = np.concatenate([np.full(int(horizontal.sum()), _HORIZONTAL_WEIGHT),
                             np.full(int(vertical.sum()), _VERTICAL_WEIGHT)])
    if seed is not None:
        weight = weight + np.random.default_rng(seed).uniform(0.0, _JITTER, size=weight.size)
    if seed is not None and weight.size <= _SMALL_MST:
        pairs = _distinct_weight_mst(src.tolist(), dst.tolist(), weight.tolist())
        if pairs is not None:
            return _tree_from_pairs(cells, *pairs)
    graph = coo_matrix((weight, (src, dst)), shape=(h * w, h * w)).tocsr()
    mst = minimum_spanning_tree(graph).tocoo()
    return _tree_from_pairs(cells, mst.row.astype(np.int64), mst.col.astype(np.int64))


def _distinct_weight_mst(src: list[int], dst: list[int], weight: list[float]
                         ) -> tuple[IntArray, IntArray] | None:
    """The minimum spanning forest's edges by Kruskal in plain Python; None on equal weights.

    With distinct weights the minimum spanning tree is unique, so this is the tree scipy's
    minimum_spanning_tree finds, without its sparse-matrix overhead (most of the cost of a
    tree of a few dozen cells: the balanced planner builds one per robot).
    """
    order = sorted(range(len(weight)), key=weight.__getitem__)
    if any(weight[a] == weight[b] for a, b in itertools.pairwise(order)):
        return None  # ties: the tree would depend on scipy's order
    root: dict[int, int] = {}

    def find(x: int) -> int:
        while (up := root.get(x, x)) != x:
            root[x] = root.get(up, up)
            x = up
        return x

    rows: list[int] = []
    cols: list[int] = []
    for i in order:
        a, b = find(src[i]), find(dst[i])
        if a != b:
            root[a] = b
            rows.append(src[i])
            cols.append(dst[i])
    return np.asarray(rows, dtype=np.int64), np.asarray(cols, dtype=np.int64)


def _tree_from_parents(cells: BoolArray, parent: list[int]) -> SpanningTree:
    parents = np.asarray(parent, dtype=np.int64)
    child = np.flatnonzero(parents >= 0)
    return _tree_from_pairs(cells, child, parents[child])


def _tree_from_pairs(cells: BoolArray, u: IntArray, v: IntArray) -> SpanningTree:
    """SpanningTree from edges given as flat cell indices (each pair 4-adjacent)."""
    h, w = cells.shape
    a = np.minimum(u, v)
    b = np.maximum(u, v)
    # same row and one column apart; checking the row keeps a one-column grid right
    horizontal = (b == a + 1) & (a // w == b // w)
    right = np.zeros(h * w, dtype=bool)
    down = np.zeros(h * w, dtype=bool)
    right[a[horizontal]] = True
    down[a[~horizontal]] = True
    return SpanningTree(cells=cells.copy(), right=right.reshape(h, w),
                        down=down.reshape(h, w))
