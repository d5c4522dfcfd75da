"""Stage two of Create Tree (paper 000, Alg. 1 lines 11-18): join the subtrees by bridges.

A bridge set is k - 1 edges between different subtrees that join them into one tree. Each set
is scored by the objective of section 3.1: the largest distance, along the STC cycle of the
joined tree, between two robots that are consecutive on it.

Scoring is batched. Bridging two cells changes exactly two successors of the forest's STC
walk (one sub-cell in each cell: the one whose walk would run along the shared side now
crosses it), so every tried tree's successor map is the forest's map with 2(k - 1) entries
replaced. The cycle positions then come from list ranking by pointer doubling, ceil(log2 n)
vectorised gathers for all tries at once, instead of walking n pointers per try in Python.
This is exactly the position stc_cycle would give (the tests check it against stc_cycle).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from planner.createtree.types import BridgeSearch, Subtrees
from planner.cycle import successor_map
from planner.types import IntArray, SpanningTree, SubCell

BATCH = 128  # tries ranked at once: bounds memory to a few MB per array


def bridge_tries(k: int, cells: int, alpha: float, *, rule: str = "max") -> int:
    """How many random bridge sets to try.

    ``rule="max"``: max{k^alpha, N} (Alg. 1 line 12, section 3.3.1); ``"power"``: k^alpha
    (section 3.2's prose and Theorem 3's O(k^alpha N)).
    """
    if rule not in ("max", "power"):
        raise ValueError(f"bridge rule must be 'max' or 'power', got {rule!r}")
    if k <= 1:
        return 1
    power = math.ceil(k ** alpha)
    return max(power, cells) if rule == "max" else power


def candidate_bridges(sub: Subtrees) -> IntArray:
    """Every edge between two different subtrees, as rows (r1, c1, r2, c2)."""
    owner = sub.owner
    horiz = (owner[:, :-1] >= 0) & (owner[:, 1:] >= 0) & (owner[:, :-1] != owner[:, 1:])
    vert = (owner[:-1, :] >= 0) & (owner[1:, :] >= 0) & (owner[:-1, :] != owner[1:, :])
    hr, hc = np.nonzero(horiz)
    vr, vc = np.nonzero(vert)
    right = np.stack([hr, hc, hr, hc + 1], axis=1)
    down = np.stack([vr, vc, vr + 1, vc], axis=1)
    return np.concatenate([right, down]).astype(np.int64)


def random_bridge_sets(sub: Subtrees, candidates: IntArray, tries: int,
                       rng: np.random.Generator) -> IntArray:
    """``tries`` random valid bridge sets, as indices into ``candidates`` (tries, k - 1).

    Each set is a random spanning tree of the subtrees' contact graph (Kruskal over the
    subtree pairs in random order), then a random bridge for each chosen pair.
    """
    k = sub.k
    if k == 1:
        return np.zeros((tries, 0), dtype=np.int64)
    a = sub.owner[candidates[:, 0], candidates[:, 1]]
    b = sub.owner[candidates[:, 2], candidates[:, 3]]
    key = np.minimum(a, b) * k + np.maximum(a, b)
    pairs, pair_of = np.unique(key, return_inverse=True)
    members = [np.flatnonzero(pair_of == p) for p in range(len(pairs))]
    ends = [(int(p) // k, int(p) % k) for p in pairs]
    out = np.empty((tries, k - 1), dtype=np.int64)
    for t in range(tries):
        parent = list(range(k))

        def find(x: int, parent: list[int] = parent) -> int:
            while parent[x] != x:
                parent[x] = parent[parent[x]]
                x = parent[x]
            return x

        chosen: list[int] = []
        for p in rng.permutation(len(pairs)).tolist():
            ra, rb = find(ends[p][0]), find(ends[p][1])
            if ra != rb:
                parent[ra] = rb
                group = members[p]
                chosen.append(int(group[rng.integers(len(group))]))
                if len(chosen) == k - 1:
                    break
        if len(chosen) != k - 1:
            raise ValueError("the subtrees do not touch: no bridge set joins them")
        out[t] = chosen
    return out


class _Ranker:
    """The forest's successor map compacted to 0..n-1, plus each bridge's two rewirings."""

    def __init__(self, sub: Subtrees, candidates: IntArray) -> None:
        forest = SpanningTree(cells=sub.owner >= 0, right=sub.right, down=sub.down)
        nxt = successor_map(forest)
        on = np.flatnonzero(nxt >= 0)
        self.width = 2 * sub.owner.shape[1]
        self.ids = np.full(nxt.size, -1, dtype=np.int64)
        self.ids[on] = np.arange(on.size)
        self.base = self.ids[nxt[on]]
        self.n = int(on.size)
        r1, c1, r2, c2 = (candidates[:, i] for i in range(4))
        is_right = r1 == r2
        # right edge: br of the left cell crosses right, tl of the right cell crosses left;
        # down edge: bl of the upper cell crosses down, tr of the lower cell crosses up
        src1 = np.where(is_right, self._id(2 * r1 + 1, 2 * c1 + 1), self._id(2 * r1 + 1, 2 * c1))
        dst1 = np.where(is_right, self._id(2 * r1 + 1, 2 * c2), self._id(2 * r2, 2 * c1))
        src2 = np.where(is_right, self._id(2 * r2, 2 * c2), self._id(2 * r2, 2 * c2 + 1))
        dst2 = np.where(is_right, self._id(2 * r1, 2 * c1 + 1), self._id(2 * r1 + 1, 2 * c1 + 1))
        self.src = np.stack([src1, src2], axis=1)
        self.dst = np.stack([dst1, dst2], axis=1)

    def _id(self, r: IntArray, c: IntArray) -> IntArray:
        return self.ids[r * self.width + c]

    def positions(self, sets: IntArray, anchor: int, targets: IntArray) -> IntArray:
        """Cycle index of each target sub-cell, counted from ``anchor``, for each set."""
        tries = sets.shape[0]
        nxt = np.tile(self.base, (tries, 1))
        rows = np.arange(tries)[:, None]
        nxt[rows, self.src[sets].reshape(tries, -1)] = self.dst[sets].reshape(tries, -1)
        pred = np.empty_like(nxt)
        np.put_along_axis(pred, nxt, np.broadcast_to(np.arange(self.n), nxt.shape), axis=1)
        last = pred[:, anchor]
        weight = np.ones_like(nxt)
        weight[np.arange(tries), last] = 0
        nxt[np.arange(tries), last] = last
        for _ in range(max(1, math.ceil(math.log2(self.n)))):
            weight = weight + np.take_along_axis(weight, nxt, axis=1)
            nxt = np.take_along_axis(nxt, nxt, axis=1)
        return (self.n - 1) - weight[:, targets]


def largest_gaps(positions: IntArray, n: int) -> IntArray:
    """Per row, the largest cycle distance between two consecutive robots."""
    ordered = np.sort(positions, axis=1)
    wrap = n - ordered[:, -1] + ordered[:, 0]
    inner = np.diff(ordered, axis=1)
    return np.maximum(inner.max(axis=1, initial=0), wrap)


def score_bridge_sets(sub: Subtrees, candidates: IntArray, sets: IntArray,
                      robots: Sequence[SubCell]) -> IntArray:
    """Largest consecutive-robot gap on the cycle of each bridged tree."""
    ranker = _Ranker(sub, candidates)
    targets = np.array([ranker.ids[r * ranker.width + c] for r, c in robots], dtype=np.int64)
    scores = [largest_gaps(ranker.positions(sets[i:i + BATCH], int(targets[0]), targets),
                           ranker.n)
              for i in range(0, len(sets), BATCH)]
    return np.concatenate(scores) if scores else np.zeros(0, dtype=np.int64)


def search_bridges(sub: Subtrees, robots: Sequence[SubCell], tries: int,
                   rng: np.random.Generator) -> BridgeSearch:
    """Try ``tries`` random bridge sets; the first one with the smallest score wins."""
    candidates = candidate_bridges(sub)
    picks = random_bridge_sets(sub, candidates, tries, rng)
    scores = score_bridge_sets(sub, candidates, picks, robots)
    edges = candidates[picks] if picks.size else np.zeros((tries, 0, 4), dtype=np.int64)
    return BridgeSearch(bridges=edges, scores=scores, best=int(np.argmin(scores)))


def join(sub: Subtrees, bridges: IntArray) -> SpanningTree:
    """The spanning tree made of the subtrees' edges and the given bridges."""
    right = sub.right.copy()
    down = sub.down.copy()
    for r1, c1, r2, _c2 in bridges.tolist():
        if r1 == r2:
            right[r1, c1] = True
        else:
            down[r1, c1] = True
    return SpanningTree(cells=sub.owner >= 0, right=right, down=down)
