"""Shortest walks over an STC cycle's sub-cells, in cycle-index space: what the re-plans
after a death (planner.offline.rebalance) measure their pieces and walks with."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from planner.cycle import cycle_graph
from planner.grid import FAR, breadth_first
from planner.types import BoolArray, Cycle, IntArray

if TYPE_CHECKING:
    from scipy.sparse import csr_matrix

NEAR = 32  # places at most this far apart (manhattan) are searched in a window first
MAX_ROWS = 128  # distance rows kept by Grid.rows (n int32 each: 6 MB at 12 000 places)
UNREACHABLE = 1 << 28  # Grid.rows' moves to a place no walk reaches (sums stay in int32)


class Grid:
    """Shortest paths over the cycle's sub-cells (breadth-first, whole-array steps), in
    cycle-index space; distance maps cached per source and sub-cells avoided.

    Most searches are between places a few moves apart (the gaps of an order of uncovered
    sub-cells, the steps of a walk along a piece); those search a window round the two
    places first. A path that leaves the window (the pair's bounding box grown by
    ``margin`` on every side) is longer than manhattan + 2 margin + 1, so a path found
    inside it no longer than that is a shortest one; otherwise, and for places more than
    NEAR apart, the whole grid is searched (and that map kept).
    On a 45 000 sub-cell map this took a re-plan at k = 100 from about 60 s to 6-7 s.
    ``rows`` gives whole rows of distances from many sources at once (scipy), for the
    refinement's many lookups from a few places.
    """

    def __init__(self, cycle: Cycle) -> None:
        self.cycle = cycle
        self.free: BoolArray = cycle.index >= 0
        self._dist: dict[tuple[int, frozenset[int]], IntArray] = {}
        self._pairs: dict[tuple[int, int], int] = {}  # distances found in a window
        self._graph: csr_matrix | None = None  # the places' adjacency, for rows()
        self._rows: dict[int, IntArray] = {}

    def from_source(self, source: int, avoid: frozenset[int] = frozenset()) -> IntArray:
        """Moves from ``source`` to each sub-cell (grid-shaped; FAR where unreachable)
        around the cycle indices ``avoid``."""
        key = (source, avoid)
        if key not in self._dist:
            self._dist[key] = self._bfs(source, avoid, self._everything())
        return self._dist[key]

    def _everything(self) -> tuple[int, int, int, int]:
        return 0, self.free.shape[0], 0, self.free.shape[1]

    def _window(self, a: int, b: int) -> tuple[tuple[int, int, int, int], int]:
        """The window round ``a`` and ``b`` (rows r0:r1, columns c0:c1) and the longest
        path inside it that is surely a shortest one."""
        (ra, ca), (rb, cb) = self.cycle.at(a), self.cycle.at(b)
        manhattan = abs(ra - rb) + abs(ca - cb)
        margin = max(manhattan, 4)
        h, w = self.free.shape
        box = (max(min(ra, rb) - margin, 0), min(max(ra, rb) + margin + 1, h),
               max(min(ca, cb) - margin, 0), min(max(ca, cb) + margin + 1, w))
        return box, manhattan + 2 * margin + 1

    def _bfs(self, source: int, avoid: frozenset[int],
             box: tuple[int, int, int, int]) -> IntArray:
        r0, r1, c0, c1 = box
        open_ = self.free[r0:r1, c0:c1].copy()
        for index in avoid:
            r, c = self.cycle.at(index)
            if r0 <= r < r1 and c0 <= c < c1:
                open_[r - r0, c - c0] = False
        sources = np.zeros(open_.shape, dtype=bool)
        r, c = self.cycle.at(source)
        sources[r - r0, c - c0] = True
        return breadth_first(open_, sources)

    def distance(self, a: int, b: int) -> int:
        ra, ca = self.cycle.at(a)
        rb, cb = self.cycle.at(b)
        if abs(ra - rb) + abs(ca - cb) <= 1:
            return abs(ra - rb) + abs(ca - cb)
        nothing: frozenset[int] = frozenset()
        if (a, nothing) in self._dist:  # a map already made serves (distances are symmetric)
            return int(self._dist[a, nothing][rb, cb])
        if (b, nothing) in self._dist:
            return int(self._dist[b, nothing][ra, ca])
        pair = (min(a, b), max(a, b))
        if pair in self._pairs:
            return self._pairs[pair]
        if abs(ra - rb) + abs(ca - cb) <= NEAR:
            box, sure = self._window(a, b)
            near = int(self._bfs(a, frozenset(), box)[rb - box[0], cb - box[2]])
            if near <= sure:
                self._pairs[pair] = near
                return near
        return int(self.from_source(a)[rb, cb])

    def path(self, a: int, b: int, avoid: frozenset[int] = frozenset()) -> list[int]:
        """Cycle indices after ``a`` up to and including ``b`` on a shortest path, around
        ``avoid`` where a way around exists (ties: up, right, down, left from ``b``)."""
        if a == b:
            return []
        if self.distance(a, b) == 1:
            return [b]
        (ra, ca), (rb, cb) = self.cycle.at(a), self.cycle.at(b)
        box, sure = self._window(a, b)
        far = abs(ra - rb) + abs(ca - cb) > NEAR
        dist = self.from_source(a, avoid - {b}) if far else self._bfs(a, avoid - {b}, box)
        if far or dist[rb - box[0], cb - box[2]] > sure:
            box = self._everything()
            dist = self.from_source(a, avoid - {b})
            if dist[rb, cb] >= FAR:
                dist = self.from_source(a)
        r0, c0 = box[0], box[2]
        h, w = dist.shape
        back = [(rb - r0, cb - c0)]
        while dist[back[-1]] > 0:
            r, c = back[-1]
            d = dist[r, c]
            back.append(next((nr, nc) for nr, nc in ((r - 1, c), (r, c + 1), (r + 1, c),
                                                     (r, c - 1))
                             if 0 <= nr < h and 0 <= nc < w and dist[nr, nc] == d - 1))
        return [self.cycle.position((r + r0, c + c0)) for r, c in back[-2::-1]]

    def walk(self, start: int, piece: Sequence[int], avoid: frozenset[int]) -> list[int]:
        """From ``start`` along ``piece`` in its order, bridging gaps around ``avoid``."""
        out: list[int] = []
        at = start
        for place in piece:
            out.extend(self.path(at, place, avoid))
            at = place
        return out

    def rows(self, sources: Sequence[int]) -> dict[int, IntArray]:
        """Moves from each source to every place, as rows in cycle-index space (int32,
        UNREACHABLE where no walk leads): scipy's breadth-first searches, many sources per
        call, the last MAX_ROWS rows kept. For many distances from a few sources (the
        re-plan's refinement); scipy is imported only when this is first called."""
        from scipy.sparse.csgraph import shortest_path

        if self._graph is None:
            self._graph = cycle_graph(self.cycle)
        wanted = list(dict.fromkeys(sources))
        missing = [s for s in wanted if s not in self._rows]
        if missing:
            found = shortest_path(self._graph, directed=False, unweighted=True,
                                  indices=missing)
            found[~np.isfinite(found)] = UNREACHABLE
            for source, row in zip(missing, found.astype(np.int32), strict=True):
                self._rows[source] = row
        out = {s: self._rows[s] for s in wanted}
        for source in list(self._rows)[:max(len(self._rows) - MAX_ROWS, 0)]:
            del self._rows[source]  # the oldest first; this call's rows are in ``out``
        return out
