"""Mutable working state of the partition (private to the balanced planner).

Cells are flat indices ``r * width + c`` of the coarse grid and neighbour lists are plain
Python lists: the growth and transfer loops touch single cells thousands of times, where
lists beat numpy element access several times over. Every change goes through a method that
can log its inverse, so a chain of transfers that turns out infeasible half-way is undone.
"""

from __future__ import annotations

import functools
from collections import deque
from collections.abc import Callable, Sequence

import numpy as np

from planner.balanced.pieces import RegionPieces
from planner.balanced.types import LeafCell, Partition, Region
from planner.types import BoolArray, Cell, IntArray, SubCell

UNCLAIMED = -1
SHARED = -2  # a cell divided between regions as leaves


class PartitionState:
    """Regions under construction: whole cells, leaves, pinned cells and loads (sub-cells).

    ``offsets`` adds per robot the moves it spends before it reaches its region (a robot
    that leaves a dead end first), so balancing evens out whole walks.
    """

    def __init__(self, cells: BoolArray, starts: Sequence[SubCell],
                 offsets: Sequence[int] | None = None) -> None:
        h, w = cells.shape
        self.width = w
        self.starts = tuple(starts)
        self.k = len(starts)
        # shared, never changed: a plan partitions the same area up to a dozen times
        self.free, self.neighbours, self.edge_src, self.edge_dst = grid_graph(
            h, w, np.asarray(cells, dtype=bool).tobytes())
        self.ring = ring_cells(h, w)
        self.label: list[int] = [UNCLAIMED] * (h * w)
        # per cell: owned (label >= 0) and next to a cell of another region. Only such a
        # whole cell can pass to a neighbour, and the scans for moves (balance.py) skip the
        # rest with one lookup: at k = 20 on 45 000 sub-cells they ran 57 million times
        # over the inner cells of regions of ~570 cells (a plan took 51 s of CPU).
        self.bordering: list[bool] = [False] * (h * w)
        self.whole: list[set[int]] = [set() for _ in range(self.k)]
        self.leaves: list[list[LeafCell]] = [[] for _ in range(self.k)]
        # load = sub-cells held + moves spent before reaching the region (travel offset)
        self.load: list[int] = list(offsets) if offsets is not None else [0] * self.k
        self.pins: dict[int, int] = {}
        self._cut: dict[int, set[int]] = {}
        self._hole_free: dict[int, bool] = {}
        self.pieces: dict[int, RegionPieces] = {}  # relieve._pieces cache
        # balance._takers cache: (robot, unit) -> (region version it was computed at, takers)
        self.takers: dict[tuple[int, int], tuple[int, list[int]]] = {}
        self.version = 0  # bumped by every change (restored by a rollback)
        self._lowest = (-1, 0)  # (version, min(load)) for lowest_load
        # balance._find_chain: unit -> ((version, limit), regions that cannot reach a taker)
        self.dead_ends: dict[int, tuple[tuple[int, int], set[int]]] = {}
        # reshape.reshape_pairs: (big, small, cells moved, their region versions) that failed
        self.failed_resplits: set[tuple[int, int, int, int, int]] = set()
        self._begun = 0
        # per region: bumped when its cells, its pins or the owner of a cell next to it change
        # (all that the moves out of a region depend on)
        self.region_version: list[int] = [0] * self.k
        self._log: list[Callable[[], None]] | None = None
        self.transfers = 0

    # -- coordinates ---------------------------------------------------------------------
    def flat(self, cell: Cell) -> int:
        return cell[0] * self.width + cell[1]

    def cell(self, u: int) -> Cell:
        r, c = divmod(u, self.width)
        return (r, c)

    def inside(self, cell: Cell) -> bool:
        r, c = cell
        h = len(self.free) // self.width
        return 0 <= r < h and 0 <= c < self.width and self.free[self.flat(cell)]

    # -- undo log ------------------------------------------------------------------------
    def begin(self) -> None:
        self._log = []
        self._begun = self.version

    def commit(self) -> None:
        self._log = None

    def rollback(self) -> None:
        log, self._log = self._log or [], None
        for undo in reversed(log):
            undo()
        self.version = self._begun  # the same cells, owners and pins as at begin()

    def _record(self, undo: Callable[[], None]) -> None:
        self.version += 1
        if self._log is not None:
            self._log.append(undo)

    # -- changes -------------------------------------------------------------------------
    def _touch(self, u: int, robot: int = UNCLAIMED) -> None:
        """Bump the version of ``robot`` and of every region owning ``u`` or a neighbour,
        and say again which of them border another region (``u``'s label changed)."""
        version, label, neighbours, bordering = (self.region_version, self.label,
                                                 self.neighbours, self.bordering)
        if robot >= 0:
            version[robot] += 1
        if label[u] >= 0:
            version[label[u]] += 1
        for x in (u, *neighbours[u]):
            own = label[x]
            if own < 0:
                bordering[x] = False
                continue
            if x != u:
                version[own] += 1
            bordering[x] = any((y := label[v]) >= 0 and y != own for v in neighbours[x])

    def claim(self, robot: int, u: int) -> None:
        """Make free cell ``u`` a whole cell of ``robot``'s region."""
        self.label[u] = robot
        self._touch(u)
        self.whole[robot].add(u)
        self.load[robot] += 4
        self._cut.pop(robot, None)
        self._hole_free.pop(robot, None)
        self.pieces.pop(robot, None)
        self.version += 1
        if self._log is not None:  # the undo closure costs more than the change itself
            self._log.append(lambda: self.release(robot, u))

    def release(self, robot: int, u: int, label: int = UNCLAIMED) -> None:
        self.whole[robot].discard(u)
        self.label[u] = label
        self._touch(u, robot)
        self.load[robot] -= 4
        self._cut.pop(robot, None)
        self._hole_free.pop(robot, None)
        self.pieces.pop(robot, None)
        self.version += 1
        if self._log is not None:
            self._log.append(lambda: self.claim(robot, u))

    def add_leaf(self, robot: int, leaf: LeafCell) -> None:
        self.leaves[robot].append(leaf)
        self.load[robot] += len(leaf.subs)
        self._record(lambda: self.remove_leaf(robot, leaf))

    def remove_leaf(self, robot: int, leaf: LeafCell) -> None:
        self.leaves[robot].remove(leaf)
        self.load[robot] -= len(leaf.subs)
        self._record(lambda: self.add_leaf(robot, leaf))

    def pin(self, u: int) -> None:
        self.pieces.pop(self.label[u], None)  # cached pieces must now keep u
        self.pins[u] = self.pins.get(u, 0) + 1
        self._touch(u)
        self._record(lambda: self.unpin(u))

    def unpin(self, u: int) -> None:
        self.pieces.pop(self.label[u], None)
        self.pins[u] -= 1
        if not self.pins[u]:
            del self.pins[u]
        self._touch(u)
        self._record(lambda: self.pin(u))

    def set_label(self, u: int, label: int) -> None:
        old = self.label[u]
        self.label[u] = label
        self._touch(u, old)
        self._record(lambda: self.set_label(u, old))

    # -- queries -------------------------------------------------------------------------
    def lowest_load(self) -> int:
        """min(load), cached for this version (failed chain searches ask it again and again)."""
        if self._lowest[0] != self.version:
            self._lowest = (self.version, min(self.load))
        return self._lowest[1]

    def pinned(self, u: int) -> bool:
        return u in self.pins

    def has_cut_cells(self, robot: int) -> bool:
        return robot in self._cut

    def cached_cut_cells(self, robot: int) -> set[int] | None:
        """The region's cut cells if known (not changed since computed), else None."""
        return self._cut.get(robot)

    def remember_cut_cells(self, robot: int, cut: set[int]) -> None:
        """Cache the region's cut cells found elsewhere (relieve's search for its pieces)."""
        self._cut[robot] = cut

    def cut_cells(self, robot: int) -> set[int]:
        """Articulation cells of the region's whole cells (cached until the region changes)."""
        cut = self._cut.get(robot)
        if cut is None:
            cut = articulation_points(self.whole[robot], self.neighbours)
            self._cut[robot] = cut
        return cut

    def is_cut(self, robot: int, u: int) -> bool:
        """Whether ``u`` is an articulation cell of the region's whole cells.

        The cached cut cells when the region has not changed since they were computed;
        else the local test, and only if it fails the cut cells (computed and cached): the
        next queries on this region then cost a set lookup.
        """
        cut = self._cut.get(robot)
        if cut is not None:
            return u in cut
        if self.locally_removable(robot, u):
            return False
        # Around no hole the local test is exact: two region cells of u's ring that no run
        # of the ring joins, joined by a path avoiding u, would close a loop round a ring
        # cell outside the region. That spares a pass over the region (Hopcroft-Tarjan).
        return (len(self.whole[robot]) > 1 and self.hole_free(robot)) or u in self.cut_cells(robot)

    def hole_free(self, robot: int) -> bool:
        """Whether the region's whole cells are connected and enclose no other cell.

        Euler number V - E + F (cells, 4-adjacent pairs, 2 x 2 blocks) of a 4-connected
        set is 1 minus its holes; cached until the region changes.
        """
        known = self._hole_free.get(robot)
        if known is None:
            known = _hole_free(self.whole[robot], self.neighbours, self.width)
            self._hole_free[robot] = known
        return known

    def locally_removable(self, robot: int, u: int) -> bool:
        """Whether ``u``'s region neighbours stay linked around it (then ``u`` is no cut).

        The 8 cells around ``u`` are walked as a ring; if the region's cells among them
        that touch ``u`` all lie in one run of region cells along the ring, removing ``u``
        cannot disconnect them. A sufficient test only (a loop round a hole is missed), so
        callers fall back to cut_cells when it says no.
        """
        label = self.label
        mask = 0
        for bit, v in self.ring[u]:
            if label[v] == robot:
                mask |= bit
        return RING_REMOVABLE[mask]

    def locally_removable_from(self, cells: set[int], u: int) -> bool:
        """locally_removable for any set of cells (``u`` in it): a sufficient no-cut test."""
        mask = 0
        for bit, v in self.ring[u]:
            if v in cells:
                mask |= bit
        return RING_REMOVABLE[mask]

    def to_partition(self, transfers: int) -> Partition:
        regions = []
        for robot in range(self.k):
            cells = tuple(sorted(self.cell(u) for u in self.whole[robot]))
            regions.append(Region(robot=robot, start=self.starts[robot], cells=cells,
                                  leaves=tuple(self.leaves[robot])))
        return Partition(regions=tuple(regions), transfers=transfers)


def _hole_free(cells: set[int], neighbours: list[list[int]], width: int) -> bool:
    """PartitionState.hole_free for one set of cells (flat indices, row width ``width``)."""
    if not cells:
        return False
    edges = blocks = 0
    for u in cells:
        right = (u + 1) % width != 0 and u + 1 in cells
        down = u + width in cells
        edges += right + down
        blocks += right and down and u + width + 1 in cells
    if len(cells) - edges + blocks != 1:
        return False
    start = next(iter(cells))  # Euler number 1 could be two parts and a hole: count parts
    seen = {start}
    stack = [start]
    while stack:
        for v in neighbours[stack.pop()]:
            if v in cells and v not in seen:
                seen.add(v)
                stack.append(v)
    return len(seen) == len(cells)


def articulation_points(nodes: set[int], neighbours: list[list[int]]) -> set[int]:
    """Cut vertices of the subgraph induced by ``nodes`` (iterative Hopcroft-Tarjan, the one
    search of planner.balanced.pieces, with no cell pinned)."""
    return RegionPieces(nodes, neighbours, _unpinned).cut


def _unpinned(cell: int) -> bool:
    return False


@functools.lru_cache(maxsize=8)
def grid_graph(h: int, w: int, cells: bytes
               ) -> tuple[list[bool], list[list[int]], IntArray, IntArray]:
    """Free flags, 4-neighbour lists and every ordered pair of neighbouring free cells
    (edge_src, edge_dst: for vectorised boundary scans) of an h x w grid given as bytes.

    Cells are flat indices ``r * w + c``. Cached: callers must not change the results.
    """
    free = [bool(b) for b in cells]
    neighbours: list[list[int]] = [[] for _ in range(h * w)]
    for u in range(h * w):
        if not free[u]:
            continue
        r, c = divmod(u, w)
        for rr, cc in ((r - 1, c), (r, c + 1), (r + 1, c), (r, c - 1)):
            if 0 <= rr < h and 0 <= cc < w and free[rr * w + cc]:
                neighbours[u].append(rr * w + cc)
    edge_src = np.asarray([u for u, vs in enumerate(neighbours) for _ in vs], dtype=np.int64)
    edge_dst = np.asarray([v for vs in neighbours for v in vs], dtype=np.int64)
    edge_src.setflags(write=False)
    edge_dst.setflags(write=False)
    return free, neighbours, edge_src, edge_dst


@functools.cache
def ring_cells(h: int, w: int) -> tuple[tuple[tuple[int, int], ...], ...]:
    """Per cell of an h x w grid, (bit, cell) for the cells of its ring (RING) on the grid."""
    return tuple(
        tuple((1 << i, (u // w + dr) * w + u % w + dc) for i, (dr, dc) in enumerate(RING)
              if 0 <= u // w + dr < h and 0 <= u % w + dc < w)
        for u in range(h * w))


def splits(nodes: set[int], neighbours: list[list[int]], v: int) -> bool:
    """Whether ``v`` is an articulation point of ``nodes``: its neighbours there fall apart.

    A breadth-first search from one neighbour that stops once it has met the others, so a
    cell on a loop costs a walk round the loop, not a pass over all of ``nodes``.
    """
    around = [x for x in neighbours[v] if x in nodes]
    if len(around) < 2:
        return False
    missing = set(around[1:])
    seen = {v, around[0]}
    queue = deque([around[0]])
    while queue:
        a = queue.popleft()
        for b in neighbours[a]:
            if b in nodes and b not in seen:
                if b in missing:
                    missing.discard(b)
                    if not missing:
                        return False
                seen.add(b)
                queue.append(b)
    return True


def _ring_removable(mask: int) -> bool:
    """The local cut test on one ring of 8 cells (bit i set: ring cell i is in the region)."""
    ring = [bool(mask >> i & 1) for i in range(8)]
    if not any(ring[1::2]):
        return False
    return all(ring) or _side_runs(ring) == 1


def _side_runs(ring: list[bool]) -> int:
    """Runs of consecutive region cells round the ring that contain a side cell.

    Adjacent ring cells are 4-adjacent to each other, so a run is connected; a corner cell
    belongs to a run only if a side next to it does too.
    """
    start = ring.index(False)
    runs = 0
    has_side = False
    inside = False
    for j in range(1, 9):
        i = (start + j) % 8
        if ring[i]:
            inside = True
            has_side = has_side or i % 2 == 1
        elif inside:
            runs += has_side
            inside = has_side = False
    return runs


# the 8 cells around a cell, in ring order (odd positions are the 4 side cells)
RING = ((-1, -1), (-1, 0), (-1, 1), (0, 1), (1, 1), (1, 0), (1, -1), (0, -1))
RING_REMOVABLE = tuple(_ring_removable(mask) for mask in range(256))
