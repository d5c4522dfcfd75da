"""Non-backtracking (nb) and simple backtracking (bt) MSTC: the paper's theorems, exhaustively."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterator

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from oracles import assert_tiles, gaps_of

from planner.allocation import allocate
from planner.types import Direction, RobotAllocation


def makespan(allocations: tuple[RobotAllocation, ...]) -> int:
    return max(a.steps for a in allocations)


def placements(n: int, k: int) -> Iterator[list[int]]:
    """Every placement up to rotation: robot 0 at index 0, the others anywhere else."""
    for rest in itertools.combinations(range(1, n), k - 1):
        yield [0, *rest]


@pytest.mark.parametrize("n", range(2, 15))
def test_nb_worst_case_is_n_minus_k_moves(n: int) -> None:
    # Theorem 5 states n - k - 1. Counting moves, the k - 1 bundled robots stay put and the
    # last one starts on its own sub-cell and must reach the n - k others: n - k moves.
    for k in range(1, n + 1):
        worst = max(makespan(allocate("nb", n, p)) for p in placements(n, k))
        assert worst == n - k
        assert makespan(allocate("nb", n, list(range(k)))) == n - k


@pytest.mark.parametrize(("n", "k"), [(12, 3), (24, 4), (2400, 30), (30, 30)])
def test_nb_best_case_equally_spaced(n: int, k: int) -> None:
    # Theorem 4: ceil(n / k - 1) when the robots are n / k apart
    positions = [i * (n // k) for i in range(k)]
    assert makespan(allocate("nb", n, positions)) == math.ceil(n / k - 1)


@pytest.mark.parametrize("n", range(3, 25))
def test_bt_worst_case_theorem_7(n: int) -> None:
    for k in range(2, min(n, 5) + 1):
        bound = n / 2 - 1 if k > 2 else math.ceil(2 * n / 3 - 1)
        for p in placements(n, k):
            bt = allocate("bt", n, p)
            assert makespan(bt) <= bound, (n, p, [(a.forward, a.backward) for a in bt])


@pytest.mark.parametrize("n", range(3, 19))
def test_bt_never_worse_than_nb_and_tiles(n: int) -> None:
    for k in range(1, min(n, 4) + 1):
        for p in placements(n, k):
            bt = allocate("bt", n, p)
            assert makespan(bt) <= makespan(allocate("nb", n, p))
            assert_tiles(n, bt)


@settings(max_examples=100, deadline=None)
@given(st.integers(5, 200).flatmap(
    lambda n: st.tuples(st.just(n), st.lists(st.integers(0, n - 1), min_size=3,
                                             max_size=min(n, 12), unique=True))))
def test_bt_keeps_nb_sections_without_a_long_one(instance: tuple[int, list[int]]) -> None:
    # Alg. 3 lines 1-4: with no section longer than half the cycle nothing is re-divided
    n, positions = instance
    _, gaps = gaps_of(n, positions)
    bt = allocate("bt", n, positions)
    nb = allocate("nb", n, positions)
    if all(2 * (g + 1) <= n for g in gaps):
        assert bt == nb
    else:
        assert makespan(bt) <= n / 2 - 1 < makespan(nb)


@settings(max_examples=100, deadline=None)
@given(st.integers(1, 300).flatmap(
    lambda n: st.tuples(st.just(n), st.lists(st.integers(0, n - 1), min_size=1,
                                             max_size=min(n, 10), unique=True))))
def test_nb_and_bt_tile_and_walk_as_promised(instance: tuple[int, list[int]]) -> None:
    n, positions = instance
    nb = allocate("nb", n, positions)
    assert_tiles(n, nb)
    assert all(a.backward == 0 for a in nb)
    assert all(leg.direction is Direction.CCW for a in nb for leg in a.legs)
    bt = allocate("bt", n, positions)
    assert_tiles(n, bt)
    for a in bt:
        assert a.start_index == positions[a.robot]
        assert len(a.legs) <= 2
        if len(a.legs) == 2:  # out over the shorter side, back across the start and on
            short, long = a.legs
            assert short.direction is not long.direction
            assert short.length == min(a.forward, a.backward)
            assert long.length == a.forward + a.backward


def test_bt_two_robots_third_apart_matches_the_paper_example() -> None:
    # section 4.1: robots a third of the cycle apart; nb leaves one robot 2/3 of the cycle
    n = 30
    nb = makespan(allocate("nb", n, [0, 10]))
    bt = makespan(allocate("bt", n, [0, 10]))
    assert nb == 19 <= math.ceil(2 * n / 3 - 1)
    # by hand: the robot with the 9-cell gap first walks x <= 9 into the 19-cell gap and back
    # (2x), then its own 9; the other walks 19 - x. x = 3 gives max(15, 16) = 16, x = 4 gives 17
    assert bt == 16


def test_bt_two_adjacent_robots_halve_the_cycle() -> None:
    # section 4.1's opening example: one empty sub-cell between two robots
    n = 40
    bt = allocate("bt", n, [0, 2])
    # the helper covers the single sub-cell and comes back (2 moves), then they meet halfway
    # in the other n - 3: max(2 + x, n - 3 - x) is smallest at ceil((n - 1) / 2)
    assert makespan(bt) == math.ceil((n - 1) / 2)
    assert makespan(allocate("nb", n, [0, 2])) == n - 3
