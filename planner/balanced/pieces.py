"""What each cell of a region alone holds to the region's pinned cells (the relieve move).

Giving a cell u away also gives the part of the region that only u links to the pinned
cells: the cells not reached from them once u is gone. Found by one search per cell, that
was a pass over the region for each of its cut cells, and with regions of 300-570 cells
(k = 20 on 18 000-45 000 sub-cells) it was the planner's largest cost. One depth-first
search from a pinned cell gives every cell's part at once: removing u cuts off exactly the
subtrees of its children c whose low point does not climb above u (low[c] >= depth[u]),
plus whatever the search never reached. The same search gives the region's cut cells
(articulation points), which relieve needs beside the pieces.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator


class RegionPieces:
    """The pieces and cut cells of one region (its whole cells ``cells``) as it stands."""

    def __init__(self, cells: set[int], neighbours: list[list[int]],
                 pinned: Callable[[int], bool]) -> None:
        self._cells = cells
        self._roots = [v for v in cells if pinned(v)]
        self._pinned = set(self._roots)
        self._order: dict[int, int] = {}  # preorder number of the search
        self._end: dict[int, int] = {}  # preorder number after the cell's subtree
        self._cut_off: dict[int, list[int]] = {}  # cell -> children whose subtree it cuts
        self.cut: set[int] = set()  # the region's articulation cells
        # The first tree grows from a pinned cell; the cells it reaches are numbered first.
        first = self._roots[:1]
        self._reached = self._search(first[0], neighbours) if first else 0
        for root in cells:  # any other part of the region, for its cut cells
            if root not in self._order:
                self._search(root, neighbours)

    def _search(self, root: int, neighbours: list[list[int]]) -> int:
        """Grow one depth-first tree from ``root``; returns the cells numbered so far."""
        cells, order, end, cut_off = self._cells, self._order, self._end, self._cut_off
        depth = {root: 0}
        low = {root: 0}
        order[root] = len(order)
        children = 0
        stack: list[tuple[int, int, Iterator[int]]] = [(root, -1, iter(neighbours[root]))]
        while stack:
            u, parent, rest = stack[-1]
            for v in rest:
                if v == parent or v not in cells:
                    continue
                seen = depth.get(v)
                if seen is None:
                    depth[v] = low[v] = depth[u] + 1
                    order[v] = len(order)
                    stack.append((v, u, iter(neighbours[v])))
                    break
                if seen < low[u]:
                    low[u] = seen
            else:  # every neighbour done: u's subtree is finished
                stack.pop()
                end[u] = len(order)
                if parent < 0:
                    continue
                if low[u] < low[parent]:
                    low[parent] = low[u]
                if low[u] >= depth[parent]:
                    cut_off.setdefault(parent, []).append(u)
                    if parent != root:
                        self.cut.add(parent)
                if parent == root:
                    children += 1
        if children >= 2:
            self.cut.add(root)
        return len(order)

    def _cuts_off(self, u: int, v: int) -> bool:
        """Whether ``v`` is no longer linked to the first pinned cell once ``u`` is gone."""
        at = self._order[v]
        if at >= self._reached:
            return True  # never reached from the pinned cells at all
        return any(self._order[c] <= at < self._end[c] for c in self._cut_off.get(u, ()))

    def size(self, u: int) -> int:
        """How many cells giving ``u`` gives (``u`` included); 0 when it cannot be given:
        ``u`` is pinned, the region has no pinned cell, or a pinned cell would go with it."""
        if not self._roots or u in self._pinned or any(self._cuts_off(u, r)
                                                      for r in self._roots):
            return 0
        unreached = len(self._cells) - self._reached - (self._order[u] >= self._reached)
        if self._order[u] >= self._reached:
            return 1 + unreached  # u is not linked to the pinned cells either way
        return 1 + unreached + sum(self._end[c] - self._order[c]
                                   for c in self._cut_off.get(u, ()))

    def cells(self, u: int) -> list[int]:
        """The piece itself: ``u``, then what it cuts off in the region's own order ([] when
        size(u) is 0)."""
        if not self.size(u):
            return []
        return [u, *(v for v in self._cells if v != u and self._cuts_off(u, v))]
