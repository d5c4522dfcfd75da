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
from planner.types import IntArray

MAX_MOVES = 64
STRETCHES = 12  # a list is cut evenly into about this many stretches, and at its gaps
MAX_CUTS = 24  # cut places per list at most (the widest gaps kept first)
_CLIP = (1 << 31) - 1  # above any cost but one through a place no walk reaches


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


def _move_one(lists: _Lists, donor: int) -> bool:
    """Make the best move of a stretch of ``donor``'s list; False if none helps."""
    work = lists.works[donor]
    if not work:
        return False
    others = _others(lists, donor)
    top = lists.costs[donor]
    steps = lists.steps[donor]
    inner = np.concatenate([[0], np.cumsum(steps)])  # inner[j] - inner[i + 1]: along i..j-1
    places = lists.places(donor)  # places[t] comes before work[t]
    rest_total = sum(lists.costs) - top
    best: tuple[tuple[int, int], int, int, int, int, bool] | None = None
    cuts = _cuts(steps)
    maps = lists.grid.rows([work[t] for t in cuts[:-1]] + [work[t - 1] for t in cuts[1:]])
    for x, i in enumerate(cuts[:-1]):
        for j in cuts[x + 1:]:
            inside = int(inner[j] - inner[i + 1])  # moves along the stretch work[i:j]
            if j < len(work):
                junction = int(maps[work[j]][places[i]])  # from the place before i
                left = top - int(steps[i]) - inside - int(steps[j]) + junction
                rest_steps = np.concatenate([steps[:i], [junction], steps[j + 1:]])
            else:
                left = top - int(steps[i]) - inside
                rest_steps = steps[:i]
            if left >= top:
                continue
            own = _slots_of(donor, np.concatenate([places[:i + 1], places[j + 1:]]),
                            rest_steps, left)
            for entry, exit_, backwards in ((work[i], work[j - 1], False),
                                            (work[j - 1], work[i], True)):
                into_map, out_map = maps[entry], maps[exit_]
                for slots in (others, own):
                    if slots is None:
                        continue
                    grown = (slots.cost + into_map[slots.before] + inside
                             + slots.has_after * (out_map[slots.after] - slots.bridge))
                    if slots is own:  # the donor's own list: only its cost changes
                        later = grown
                        totals = grown + rest_total
                    else:
                        later = np.maximum(grown, left)
                        totals = grown + left + rest_total - slots.cost
                    # one argmin over (later, total), both clipped below 2^31
                    at = int(np.argmin(np.minimum(later, _CLIP) * (_CLIP + 1)
                                       + np.minimum(totals, _CLIP)))
                    key = (int(later[at]), int(totals[at]))
                    if key[0] < top and (best is None or key < best[0]):
                        best = (key, i, j, int(slots.robot[at]), int(slots.index[at]),
                                backwards)
    if best is None:
        return False
    _, i, j, taker, at, backwards = best
    stretch = work[i:j][::-1] if backwards else work[i:j]
    rest = work[:i] + work[j:]
    if taker == donor:
        lists.replace(donor, rest[:at] + stretch + rest[at:])
    else:
        lists.replace(donor, rest)
        target = lists.works[taker]
        lists.replace(taker, target[:at] + stretch + target[at:])
    return True
