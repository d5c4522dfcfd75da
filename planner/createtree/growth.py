"""Stage one of Create Tree (paper 000, Alg. 1 lines 1-10): grow one subtree per robot.

Each round every subtree adds one cell (two when hilling): first a main branch that steps to
the free neighbour farthest from the other robots, then hills that stretch the main branch
sideways, then a breadth-first branch-out from the robot's start. Cells are only ever taken,
never released, so a hill or branch-out that fails once fails for good; that is what makes
the per-robot work lists below amortised O(N).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy.sparse import coo_array
from scipy.sparse.csgraph import shortest_path

from planner.createtree.types import Subtrees
from planner.types import BoolArray, Cell

STEPS: tuple[Cell, ...] = ((-1, 0), (1, 0), (0, -1), (0, 1))
MEASURES = ("manhattan", "euclidean", "path")

Distance = Callable[[Cell, Cell], float]
FloatArray = npt.NDArray[np.float64]


@dataclass
class _Grower:
    """Mutable state of one subtree while it grows (private to this module)."""

    ident: int
    path: list[Cell]
    phase: str = "main"
    pairs: list[tuple[Cell, Cell]] = field(default_factory=list)
    queue: deque[Cell] = field(default_factory=deque)


def path_distances(cells: BoolArray) -> FloatArray:
    """All-pairs shortest-path lengths between the free cells (inf across components).

    Indexed by the row-major rank of each free cell. csgraph's BFS-based Dijkstra on the
    unweighted 4-neighbour graph does 600 cells in a few milliseconds.
    """
    h, w = cells.shape
    ids = np.full((h, w), -1, dtype=np.int64)
    ids[cells] = np.arange(int(cells.sum()))
    horiz = cells[:, :-1] & cells[:, 1:]
    vert = cells[:-1, :] & cells[1:, :]
    a = np.concatenate([ids[:, :-1][horiz], ids[:-1, :][vert]])
    b = np.concatenate([ids[:, 1:][horiz], ids[1:, :][vert]])
    n = int(cells.sum())
    graph = coo_array((np.ones(len(a)), (a, b)), shape=(n, n)).tocsr()
    return np.asarray(shortest_path(graph, directed=False, unweighted=True))


def distance_function(cells: BoolArray, measure: str) -> Distance:
    """The paper's three measures between two cells (section 3.2.1)."""
    if measure == "manhattan":
        return lambda a, b: float(abs(a[0] - b[0]) + abs(a[1] - b[1]))
    if measure == "euclidean":
        return lambda a, b: float(np.hypot(a[0] - b[0], a[1] - b[1]))
    if measure == "path":
        table = path_distances(cells)
        ids = np.full(cells.shape, -1, dtype=np.int64)
        ids[cells] = np.arange(int(cells.sum()))
        return lambda a, b: float(table[ids[a], ids[b]])
    raise ValueError(f"unknown distance measure {measure!r}; expected one of {MEASURES}")


class _Forest:
    """Ownership and edges shared by all growers; one method per growth move."""

    def __init__(self, cells: BoolArray, roots: Sequence[Cell], distance: Distance,
                 rng: np.random.Generator) -> None:
        self.cells = cells
        self.owner = np.full(cells.shape, -1, dtype=np.int64)
        self.right = np.zeros(cells.shape, dtype=bool)
        self.down = np.zeros(cells.shape, dtype=bool)
        self.distance = distance
        self.rng = rng
        self.growers = [_Grower(i, [root]) for i, root in enumerate(roots)]
        for i, root in enumerate(roots):
            self.owner[root] = i

    def free(self, cell: Cell) -> bool:
        r, c = cell
        h, w = self.cells.shape
        return 0 <= r < h and 0 <= c < w and bool(self.cells[r, c]) and self.owner[r, c] < 0

    def set_edge(self, a: Cell, b: Cell, value: bool) -> None:
        (r1, c1), (r2, _c2) = sorted((a, b))
        if r1 == r2:
            self.right[r1, c1] = value
        else:
            self.down[r1, c1] = value

    def take(self, grower: _Grower, cell: Cell, parent: Cell) -> None:
        self.owner[cell] = grower.ident
        self.set_edge(parent, cell, True)

    def step(self, grower: _Grower) -> bool:
        """One round for one subtree; False once it can never grow again."""
        if grower.phase == "main":
            if self.extend_main(grower):
                return True
            grower.phase = "hill"
            path = grower.path
            grower.pairs = [(path[i], path[i + 1]) for i in range(len(path) - 1)]
        if grower.phase == "hill":
            if self.hill(grower):
                return True
            grower.phase = "bfs"
            grower.queue = deque(self.tree_order(grower))
        return self.branch_out(grower)

    def extend_main(self, grower: _Grower) -> bool:
        head = grower.path[-1]
        options = [(head[0] + dr, head[1] + dc) for dr, dc in STEPS]
        options = [cell for cell in options if self.free(cell)]
        if not options:
            return False
        others = [g.path[-1] for g in self.growers if g.ident != grower.ident]
        scores = [min((self.distance(cell, o) for o in others), default=0.0)
                  for cell in options]
        best = max(scores)
        # ties are common on open grids: the seeded generator breaks them
        tied = [cell for cell, s in zip(options, scores, strict=True) if s == best]
        choice = tied[int(self.rng.integers(len(tied)))]
        self.take(grower, choice, head)
        grower.path.append(choice)
        return True

    def hill(self, grower: _Grower) -> bool:
        """Replace a main-branch edge a-b by a-a'-b'-b through two free side cells."""
        while grower.pairs:
            a, b = grower.pairs[-1]
            dr, dc = b[0] - a[0], b[1] - a[1]
            for sr, sc in ((dc, dr), (-dc, -dr)):
                a2, b2 = (a[0] + sr, a[1] + sc), (b[0] + sr, b[1] + sc)
                if self.free(a2) and self.free(b2):
                    grower.pairs.pop()
                    self.set_edge(a, b, False)
                    self.take(grower, a2, a)
                    self.take(grower, b2, a2)
                    self.set_edge(b2, b, True)
                    at = grower.path.index(b)
                    grower.path[at:at] = [a2, b2]
                    grower.pairs.extend([(a, a2), (a2, b2), (b2, b)])
                    return True
            grower.pairs.pop()
        return False

    def tree_order(self, grower: _Grower) -> list[Cell]:
        """The subtree's cells breadth-first from its root, along its own edges."""
        root = grower.path[0]
        order, seen = [root], {root}
        for cell in order:
            r, c = cell
            for nb, linked in (((r, c + 1), self.right[r, c]),
                               ((r + 1, c), self.down[r, c]),
                               ((r, c - 1), c > 0 and self.right[r, c - 1]),
                               ((r - 1, c), r > 0 and self.down[r - 1, c])):
                if linked and nb not in seen:
                    seen.add(nb)
                    order.append(nb)
        return order

    def branch_out(self, grower: _Grower) -> bool:
        while grower.queue:
            cell = grower.queue[0]
            for dr, dc in STEPS:
                nb = (cell[0] + dr, cell[1] + dc)
                if self.free(nb):
                    self.take(grower, nb, cell)
                    grower.queue.append(nb)
                    return True
            grower.queue.popleft()
        return False


def grow_subtrees(cells: BoolArray, roots: Sequence[Cell], *, measure: str = "manhattan",
                  rng: np.random.Generator) -> Subtrees:
    """Grow disjoint subtrees from ``roots`` (distinct cells) until none can grow.

    Every cell of ``cells`` connected to a root ends up in exactly one subtree (Lemma 2).
    """
    forest = _Forest(cells, roots, distance_function(cells, measure), rng)
    active = list(forest.growers)
    while active:
        active = [g for g in active if forest.step(g)]
    return Subtrees(owner=forest.owner, right=forest.right, down=forest.down,
                    roots=tuple(roots))
