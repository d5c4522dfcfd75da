"""Refining a re-plan after a death: stretches of the last survivor's work moved elsewhere.

Every re-plan of planner.offline.rebalance cuts the work by one rule (pieces of one order,
or regions grown from the survivors, walked in their STC order) and keeps each piece's
order. None of them moves a stretch of work to where a survivor passes by anyway. This
local search does (the "or-opt" move of vehicle routing). Each move:

- takes a stretch of the last survivor's work list, cut at its gaps and evenly;
- inserts it, in either direction, between two places of another survivor's list, or
  elsewhere in its own;
- must leave both lists finishing before the last survivor did.

The move that leaves the later of the two finishes smallest is made, until none helps or
MAX_MOVES were made. A list's cost is the walk along it: shortest paths between
consecutive places (planner.offline.shortest: ``Grid.distance``, and ``Grid.rows`` for
the distances from a stretch's ends to every place).

Integer costs and fixed orders (the first best move on a tie, survivors in the given
order), so every survivor computes the same result from the same inputs; a place stays
in exactly one list.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from planner.offline.shortest import Grid
from planner.types import BoolArray, IntArray

MAX_MOVES = 64
STRETCHES = 12  # a list is cut evenly into about this many stretches, and at its gaps
MAX_CUTS = 24  # cut places per list at most (the widest gaps kept first)
_CLIP = (1 << 31) - 1  # above any cost but one through a place no walk reaches
_BLOCK = 1 << 16  # slots weighed in one array step (stretches x slots): 512 kB, in cache


def refined(grid: Grid, positions: Sequence[int], works: Sequence[Sequence[int]], *,
            moves: int = MAX_MOVES) -> list[list[int]]:
    """``works`` (each survivor's places in walking order, from ``positions``) with
    stretches moved while that lets the survivor who finishes last finish sooner, without
    another finishing as late."""
    lists = _Lists(grid, list(positions), [list(w) for w in works])
    for _ in range(moves):
        last = max(range(len(lists.works)), key=lambda r: (lists.costs[r], -r))
        if not _move_one(lists, last):
            break
    return lists.works


class _Lists:
    """The work lists being refined: per survivor its places, the moves to each from the
    one before (its position first), and their sum."""

    def __init__(self, grid: Grid, positions: list[int], works: list[list[int]]) -> None:
        self.grid = grid
        self.positions = positions
        self.works = works
        self.steps = [self._steps(r) for r in range(len(works))]
        self.costs = [int(s.sum()) for s in self.steps]

    def _steps(self, robot: int) -> IntArray:
        work = self.works[robot]
        before = [self.positions[robot], *work][:len(work)]
        return np.array([self.grid.distance(a, b) for a, b in zip(before, work, strict=True)],
                        dtype=np.int64)

    def replace(self, robot: int, work: list[int]) -> None:
        self.works[robot] = work
        self.steps[robot] = self._steps(robot)
        self.costs[robot] = int(self.steps[robot].sum())

    def places(self, robot: int) -> IntArray:
        """The robot's position and then its places."""
        return np.asarray([self.positions[robot], *self.works[robot]], dtype=np.int64)


@dataclass(frozen=True)
class _Slots:
    """Places a stretch may be inserted: between ``before`` and ``after`` (at a list's end
    ``after`` is any place and ``has_after`` 0)."""

    robot: IntArray
    index: IntArray  # insert before this position of the robot's list
    before: IntArray  # cycle indices
    after: IntArray
    has_after: IntArray
    bridge: IntArray  # moves from before to after now
    cost: IntArray  # the list's cost without the stretch


def _slots_of(robot: int, places: IntArray, steps: IntArray, cost: int) -> _Slots:
    """The slots of one list: ``places`` its position and places, ``steps`` the moves to
    each place from the one before."""
    n = len(places) - 1
    after = np.concatenate([places[1:], places[-1:]])
    return _Slots(np.full(n + 1, robot, dtype=np.int64), np.arange(n + 1, dtype=np.int64),
                  places, after,
                  np.concatenate([np.ones(n, dtype=np.int64), [0]]),
                  np.concatenate([steps, [0]]), np.full(n + 1, cost, dtype=np.int64))


def _others(lists: _Lists, donor: int) -> _Slots | None:
    """Every slot in the lists of all survivors but ``donor``."""
    parts = [_slots_of(r, lists.places(r), lists.steps[r], lists.costs[r])
             for r in range(len(lists.works)) if r != donor]
    if not parts:
        return None

    def joined(name: str) -> IntArray:
        return np.concatenate([getattr(p, name) for p in parts])

    return _Slots(joined("robot"), joined("index"), joined("before"), joined("after"),
                  joined("has_after"), joined("bridge"), joined("cost"))


def _cuts(steps: IntArray) -> list[int]:
    """Where the donor's list may be cut: its ends, every len/STRETCHES places and at its
    gaps (a step longer than one move), the widest gaps first up to MAX_CUTS."""
    n = len(steps)
    cuts = {round(n * j / STRETCHES) for j in range(STRETCHES + 1)}
    for t in np.argsort(-steps[1:], kind="stable") + 1:
        if len(cuts) >= MAX_CUTS or steps[t] <= 1:
            break
        cuts.add(int(t))
    return sorted(cuts)


@dataclass(frozen=True)
class _Stretches:
    """The stretches ``work[i:j]`` of a donor's list that shorten it when taken out, in
    the order of the pairs of cuts, and the rows of distances from their ends."""

    first: IntArray  # i
    last: IntArray  # j
    inside: IntArray  # moves along the stretch
    has_next: IntArray  # 1 if a place follows the stretch (j < len(work))
    junction: IntArray  # moves from the place before it to the place after it
    left: IntArray  # the donor's cost without it
    table: IntArray  # distances from a few places to every place, a row per place
    row_first: IntArray  # row of work[i]
    row_last: IntArray  # row of work[j - 1]


def _stretches(lists: _Lists, donor: int) -> _Stretches | None:
    work = lists.works[donor]
    n, top = len(work), lists.costs[donor]
    steps = lists.steps[donor]
    inner = np.concatenate([[0], np.cumsum(steps)])  # inner[j] - inner[i + 1]: along i..j-1
    places = lists.places(donor)  # places[t] comes before work[t]
    cuts = _cuts(steps)
    maps = lists.grid.rows([work[t] for t in cuts[:-1]] + [work[t - 1] for t in cuts[1:]])
    row_of = {place: r for r, place in enumerate(maps)}
    table = np.stack(list(maps.values()))
    pairs = np.array([(i, j) for x, i in enumerate(cuts[:-1]) for j in cuts[x + 1:]],
                     dtype=np.int64)
    first, last = pairs[:, 0], pairs[:, 1]
    inside = inner[last] - inner[first + 1]
    has_next = (last < n).astype(np.int64)
    following = np.minimum(last, n - 1)

    def rows(at: IntArray) -> IntArray:
        return np.array([row_of[work[int(t)]] for t in at], dtype=np.int64)

    junction = has_next * table[rows(following), places[first]]
    left = top - steps[first] - inside + has_next * (junction - steps[following])
    keep = left < top
    if not keep.any():
        return None
    return _Stretches(first[keep], last[keep], inside[keep], has_next[keep], junction[keep],
                      left[keep], table, rows(first[keep]), rows(last[keep] - 1))


def _move_one(lists: _Lists, donor: int) -> bool:
    """Make the best move of a stretch of ``donor``'s list; False if none helps.

    Every stretch, both directions and every slot are weighed in whole-array steps, a
    block of stretches at a time. The move made is the one a loop over the stretches,
    then the directions, then the other lists' slots before the donor's own would keep
    first: the least (later finish, total), the first on a tie."""
    work = lists.works[donor]
    if not work:
        return False
    found = _stretches(lists, donor)
    if found is None:
        return False
    n = len(work)
    top = lists.costs[donor]
    steps = lists.steps[donor]
    places = lists.places(donor)
    table = found.table
    others = _others(lists, donor)
    rest_total = sum(lists.costs) - top
    # The donor's own slots: every place t of its list (the stretch's are masked per pair).
    own_after = np.concatenate([places[1:], places[-1:]])
    own_has_after = np.concatenate([np.ones(n, dtype=np.int64), [0]])
    own_bridge = np.concatenate([steps, [0]])
    t = np.arange(n + 1, dtype=np.int64)
    width = max(n + 1, 0 if others is None else len(others.before))
    block = max(1, _BLOCK // width)
    best: tuple[int, int, int, int] | None = None  # (later, total, stretch, candidate)
    move: tuple[int, int, bool] = (0, 0, False)  # (taker, slot, backwards) of the best
    for lo in range(0, len(found.first), block):
        part = slice(lo, lo + block)
        ii, jj, ins, lft = found.first[part], found.last[part], found.inside[part], found.left[part]
        candidates = []
        for entry, exit_, backwards in ((found.row_first[part], found.row_last[part], False),
                                        (found.row_last[part], found.row_first[part], True)):
            into, out = entry[:, None], exit_[:, None]
            if others is not None:
                grown = (others.cost + table[into, others.before] + ins[:, None]
                         + others.has_after * (table[out, others.after] - others.bridge))
                later = np.maximum(grown, lft[:, None])
                totals = grown + lft[:, None] + (rest_total - others.cost)
                at = _argmin(later, totals)
                candidates.append((later, totals, at, others.robot[at], others.index[at],
                                   backwards))
            grown = (lft[:, None] + table[into, places] + ins[:, None]
                     + own_has_after * (table[out, own_after] - own_bridge))
            # the slot after place i: before the stretch's next place, or the list's end
            grown[np.arange(len(ii)), ii] = (
                lft + table[entry, places[ii]] + ins
                + found.has_next[part]
                * (table[exit_, places[np.minimum(jj + 1, n)]] - found.junction[part]))
            totals = grown + rest_total
            at = _argmin(grown, totals, (t > ii[:, None]) & (t <= jj[:, None]))
            candidates.append((grown, totals, at, np.full(len(ii), donor),
                               np.where(at <= ii, at, at - (jj - ii)), backwards))
        for c, (later, totals, at, takers, indices, backwards) in enumerate(candidates):
            rows = np.arange(len(ii))
            key_later, key_total = later[rows, at], totals[rows, at]
            helps = key_later < top
            if not helps.any():
                continue
            least = key_later == key_later[helps].min()
            least &= key_total == key_total[least].min()
            p = int(np.argmax(least))  # the first stretch of this kind with the least key
            key = (int(key_later[p]), int(key_total[p]), lo + p, c)
            if best is None or key < best:
                best = key
                move = (int(takers[p]), int(indices[p]), backwards)
    if best is None:
        return False
    i, j = int(found.first[best[2]]), int(found.last[best[2]])
    taker, slot, backwards = move
    stretch = work[i:j][::-1] if backwards else work[i:j]
    rest = work[:i] + work[j:]
    if taker == donor:
        lists.replace(donor, rest[:slot] + stretch + rest[slot:])
    else:
        lists.replace(donor, rest)
        target = lists.works[taker]
        lists.replace(taker, target[:slot] + stretch + target[slot:])
    return True


def _argmin(later: IntArray, totals: IntArray, masked: BoolArray | None = None) -> IntArray:
    """Per row, the first slot with the least (later, total), both clipped below 2^31;
    never a ``masked`` one (a row's own stretch)."""
    key = np.minimum(later, _CLIP) * (_CLIP + 1) + np.minimum(totals, _CLIP)
    if masked is not None:
        key[masked] = np.iinfo(np.int64).max
    return np.argmin(key, axis=1)
