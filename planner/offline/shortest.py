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
# Up to this many places every distance is found at once, on first need (scipy, n x n int32:
# 4 MB at 1 024; 0.05 s at 768). Four re-plans of 11 robots on 480 places asked 142 000
# distances, and the window searches behind them took 6.2 of their 11.7 s of CPU. At 2 400
# places a table is no faster (docs/balanced.md).
ALL_PAIRS_MAX = 1024
_CHUNK = 256  # sources per scipy call while the table is made (a float64 block of n each)


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
    refinement's many lookups from a few places. On maps of at most ALL_PAIRS_MAX places
    all of this gives way to one table of every distance, made on first need: there the
    searches cost more than the table (a re-plan of 11 robots on 908 places: 2.33 -> 1.44 s
    of CPU, the same re-plan).
    """

    def __init__(self, cycle: Cycle) -> None:
        self.cycle = cycle
        self.free: BoolArray = cycle.index >= 0
        self._dist: dict[tuple[int, frozenset[int]], IntArray] = {}
        self._pairs: dict[tuple[int, int], int] = {}  # distances found in a window
        self._graph: csr_matrix | None = None  # the places' adjacency, for rows()
        self._rows: dict[int, IntArray] = {}
        self._table: IntArray | None = None  # every distance, on small maps (ALL_PAIRS_MAX)

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
        """Moves from place ``a`` to place ``b`` (FAR where no walk leads)."""
        n = self.cycle.n
        if n <= ALL_PAIRS_MAX:  # indices wrap round the cycle, as Cycle.at's do
            moves = int(self._all_pairs()[a % n, b % n])
            return FAR if moves >= UNREACHABLE else moves
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

    def distances(self, sources: Sequence[int], targets: Sequence[int]) -> IntArray:
        """Moves from each of ``sources`` (rows) to each of ``targets`` (columns), int64,
        FAR where no walk leads: one lookup on small maps, else one ``distance`` each."""
        n = self.cycle.n
        if n <= ALL_PAIRS_MAX:
            found = self._all_pairs()[np.ix_(np.asarray(sources) % n,
                                             np.asarray(targets) % n)].astype(np.int64)
            found[found >= UNREACHABLE] = FAR
            return found
        return np.array([[self.distance(s, t) for t in targets] for s in sources],
                        dtype=np.int64).reshape(len(sources), len(targets))

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
        call, the last MAX_ROWS rows kept (rows of the table on small maps). For many
        distances from a few sources (the re-plan's refinement)."""
        if self.cycle.n <= ALL_PAIRS_MAX:
            table = self._all_pairs()
            return {s: table[s % self.cycle.n] for s in dict.fromkeys(sources)}
        wanted = list(dict.fromkeys(sources))
        missing = [s for s in wanted if s not in self._rows]
        if missing:
            for source, row in zip(missing, self._search(missing), strict=True):
                self._rows[source] = row
        out = {s: self._rows[s] for s in wanted}
        for source in list(self._rows)[:max(len(self._rows) - MAX_ROWS, 0)]:
            del self._rows[source]  # the oldest first; this call's rows are in ``out``
        return out

    def _all_pairs(self) -> IntArray:
        """Every distance (int32, UNREACHABLE where no walk leads), made on first need."""
        if self._table is None:
            places = range(self.cycle.n)
            self._table = np.concatenate([self._search(list(places[i:i + _CHUNK]))
                                          for i in range(0, self.cycle.n, _CHUNK)])
        return self._table

    def _search(self, sources: list[int]) -> IntArray:
        """Moves from each of ``sources`` to every place (rows, int32, UNREACHABLE where no
        walk leads): scipy's breadth-first searches; scipy is imported on first need."""
        from scipy.sparse.csgraph import shortest_path

        if self._graph is None:
            self._graph = cycle_graph(self.cycle)
        found = shortest_path(self._graph, directed=False, unweighted=True, indices=sources)
        found[~np.isfinite(found)] = UNREACHABLE
        return found.astype(np.int32).reshape(len(sources), self.cycle.n)
