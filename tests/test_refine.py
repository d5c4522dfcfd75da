"""The refinement of a re-plan (planner.offline.refine): stretches of work moved between
survivors and within one survivor's list keep every place in exactly one list, never let the
last survivor finish later, and find the obvious improvements; costs checked against a
breadth-first oracle of the tests' own."""

from __future__ import annotations

from collections import deque
from itertools import pairwise

import numpy as np
import pytest

from planner.offline.refine import _cuts, refined
from planner.offline.shortest import Grid
from planner.types import Cycle


def grid_of(free: np.ndarray) -> Grid:
    """Grid needs each free sub-cell's index only, not a real STC cycle."""
    path = np.argwhere(free)
    index = np.full(free.shape, -1)
    index[free] = np.arange(len(path))
    return Grid(Cycle(path, index))


class Oracle:
    """Breadth-first moves between places, the tests' own (one map per source)."""

    def __init__(self, grid: Grid) -> None:
        self.grid = grid
        self.free = grid.cycle.index >= 0
        self.maps: dict[int, dict[tuple[int, int], int]] = {}

    def moves(self, a: int, b: int) -> int:
        if a not in self.maps:
            self.maps[a] = self._from(a)
        r, c = self.grid.cycle.at(b)
        return self.maps[a][int(r), int(c)]

    def cost(self, position: int, work: list[int]) -> int:
        return sum(self.moves(a, b) for a, b in pairwise([position, *work]))

    def _from(self, a: int) -> dict[tuple[int, int], int]:
        r0, c0 = self.grid.cycle.at(a)
        seen = {(int(r0), int(c0)): 0}
        queue = deque(seen)
        h, w = self.free.shape
        while queue:
            r, c = queue.popleft()
            for nr, nc in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
                if 0 <= nr < h and 0 <= nc < w and self.free[nr, nc] and (nr, nc) not in seen:
                    seen[nr, nc] = seen[r, c] + 1
                    queue.append((nr, nc))
        return seen


def corridor(length: int) -> Grid:
    return grid_of(np.ones((1, length), dtype=bool))


def test_a_survivor_with_nothing_left_takes_the_far_half_of_a_corridor() -> None:
    grid = corridor(40)
    oracle = Oracle(grid)
    works = refined(grid, [0, 39], [list(range(1, 39)), []])
    assert sorted(works[0] + works[1]) == list(range(1, 39))
    finish = max(oracle.cost(0, works[0]), oracle.cost(39, works[1]))
    assert finish <= 21  # 19 each at best; 37 before
    assert works[1] and works[1][0] == 38  # it starts next to itself


def test_a_list_walked_back_and_forth_is_put_in_order() -> None:
    grid = corridor(40)
    oracle = Oracle(grid)
    work = list(range(20, 40)) + list(range(1, 20))  # out to the end, then all the way back
    assert oracle.cost(0, work) == 20 + 19 + 38 + 18
    (better,) = refined(grid, [0], [work])
    assert sorted(better) == list(range(1, 40))
    assert oracle.cost(0, better) <= 45  # 39 at best


def test_a_stretch_walked_backwards_is_turned_round_where_it_is() -> None:
    grid = corridor(40)
    work = [1, 2, 3, *range(10, 3, -1), *range(11, 21)]  # 3 -> 10 down to 4 -> 11
    (better, far) = refined(grid, [0, 39], [work, []], moves=1)
    assert (better, far) == (list(range(1, 21)), [])  # the one move that makes it 20


def random_lists(seed: int, shape: tuple[int, int]) -> tuple[Grid, list[int], list[list[int]]]:
    """2-5 survivors' positions and work lists: random places of the largest 4-connected
    part of a random map (every place reachable from every other), in random order."""
    rng = np.random.default_rng(seed)
    free = rng.random(shape) > 0.25
    grid = grid_of(free)
    index = grid.cycle.index
    parts = np.full(free.shape, -1)
    part = 0
    for r, c in np.argwhere(free):
        if parts[r, c] >= 0:
            continue
        parts[r, c] = part
        queue = deque([(r, c)])
        while queue:
            y, x = queue.popleft()
            for ny, nx in ((y - 1, x), (y + 1, x), (y, x - 1), (y, x + 1)):
                if (0 <= ny < free.shape[0] and 0 <= nx < free.shape[1] and free[ny, nx]
                        and parts[ny, nx] < 0):
                    parts[ny, nx] = part
                    queue.append((ny, nx))
        part += 1
    biggest = np.bincount(parts[free]).argmax()
    places = [int(i) for i in index[(parts == biggest) & free]]
    rng.shuffle(places)
    k = int(rng.integers(2, 6))
    positions, rest = places[:k], places[k:len(places) * 2 // 3]
    cuts = sorted(rng.choice(np.arange(1, len(rest)), size=k - 1, replace=False).tolist())
    works = [[int(i) for i in w] for w in np.split(np.asarray(rest), cuts)]
    return grid, positions, works


@pytest.mark.parametrize("seed", range(12))
def test_every_place_stays_in_one_list_and_the_last_finishes_no_later(seed: int) -> None:
    grid, positions, works = random_lists(seed, (14, 18))
    rest = [i for w in works for i in w]
    oracle = Oracle(grid)
    before = max(oracle.cost(p, w) for p, w in zip(positions, works, strict=True))
    after_works = refined(grid, positions, works, moves=12)  # random lists: many moves help
    assert sorted(i for w in after_works for i in w) == sorted(rest)
    after = max(oracle.cost(p, w) for p, w in zip(positions, after_works, strict=True))
    assert after <= before
    assert after < before or after_works == works  # a move is made only when it helps
    assert refined(grid, positions, works, moves=12) == after_works  # the same inputs, result


def best_move_by_enumeration(oracle: Oracle, positions: list[int], works: list[list[int]]
                             ) -> list[list[int]]:
    """The refinement's one move as its docstring states it, by trying every one and
    costing the lists it leaves with the tests' own breadth-first moves: a stretch of the
    last survivor's list between two of its cuts (``_cuts``), put in either direction into
    any slot of another survivor's list or of its own; the move whose later finish of the
    two, then the total of all lists, is least, first in the order stretches, directions,
    the others' slots (by survivor, then place) before its own; only if that finish is
    below the last survivor's."""
    costs = [oracle.cost(p, w) for p, w in zip(positions, works, strict=True)]
    donor = max(range(len(works)), key=lambda r: (costs[r], -r))
    work = works[donor]
    steps = np.array([oracle.moves(a, b) for a, b in pairwise([positions[donor], *work])])
    cuts = _cuts(steps)
    best: tuple[tuple[int, int], list[list[int]]] | None = None
    for x, i in enumerate(cuts[:-1]):
        for j in cuts[x + 1:]:
            rest = work[:i] + work[j:]
            for stretch in (work[i:j], work[i:j][::-1]):
                for taker in [r for r in range(len(works)) if r != donor] + [donor]:
                    target = rest if taker == donor else works[taker]
                    left = oracle.cost(positions[donor], rest)
                    for at in range(len(target) + 1):
                        taken = target[:at] + stretch + target[at:]
                        grown = oracle.cost(positions[taker], taken)
                        if taker == donor:
                            key = (grown, sum(costs) - costs[donor] + grown)
                        else:
                            key = (max(left, grown),
                                   sum(costs) - costs[donor] - costs[taker] + left + grown)
                        if key[0] < costs[donor] and (best is None or key < best[0]):
                            trial = [list(w) for w in works]
                            trial[donor] = rest
                            trial[taker] = taken
                            best = (key, trial)
    return works if best is None else best[1]


@pytest.mark.parametrize("seed", range(24))
def test_the_move_made_is_the_best_one_by_enumeration(seed: int) -> None:
    grid, positions, works = random_lists(100 + seed, (6, 8))
    assert refined(grid, positions, works, moves=1) == best_move_by_enumeration(
        Oracle(grid), positions, works)
