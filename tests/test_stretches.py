"""planner.stretches on a line (the re-plan's uncovered work, with gaps between places):
reaches against brute force, and the greedy's splits valid and never below the optimum. The
cycle mode is tested through the balanced planner's split (tests/test_balanced_split.py)."""

from __future__ import annotations

import itertools
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.stretches import Reach, Stretch


@st.composite
def lines(draw: st.DrawFn) -> tuple[np.ndarray, np.ndarray]:
    """Places on a number line (positions nondecreasing, gaps of 1-4 moves) and robots
    standing on the line with a load each: walk = load + distance along the line, which
    grows by at most the gap between neighbouring places, as a shortest walk does."""
    n = draw(st.integers(1, 9))
    gaps = draw(st.lists(st.integers(1, 4), min_size=n - 1, max_size=n - 1))
    positions = np.concatenate([[0], np.cumsum(gaps, dtype=np.int64)]).astype(np.int64)
    k = draw(st.integers(1, 3))
    span = int(positions[-1])
    rows = []
    for _ in range(k):
        at = draw(st.integers(-3, span + 3))
        load = draw(st.integers(0, 5))
        rows.append(load + np.abs(positions - at))
    return np.array(rows, dtype=np.int64), positions


def line_cost(walks: np.ndarray, positions: np.ndarray, s: Stretch) -> int:
    return int(walks[s.robot, s.entry]) + int(positions[s.end - 1] - positions[s.first])


@settings(max_examples=200, deadline=None)
@given(lines(), st.integers(0, 30), st.integers(0, 8))
def test_reach_on_a_line_is_the_farthest_end_within_the_bound(
        line: tuple[np.ndarray, np.ndarray], bound: int, at: int) -> None:
    walks, positions = line
    k, n = walks.shape
    at %= n
    ends, _ = Reach(walks, positions=positions).reach(at, bound, np.arange(k))
    for j in range(k):
        fits = [e for e in range(at + 1, n + 1)
                if min(line_cost(walks, positions, Stretch(j, at, e, True)),
                       line_cost(walks, positions, Stretch(j, at, e, False))) <= bound]
        assert ends[j] == max(fits, default=at)


def brute_force_line(walks: np.ndarray, positions: np.ndarray) -> int:
    """The smallest finish of any cut of the line into stretches, one robot each at most."""
    k, n = walks.shape
    best = math.inf
    for parts in range(1, min(k, n) + 1):
        for inner in itertools.combinations(range(1, n), parts - 1):
            cuts = (0, *inner, n)
            for robots in itertools.permutations(range(k), parts):
                worst = max(min(line_cost(walks, positions, Stretch(r, a, b, True)),
                                line_cost(walks, positions, Stretch(r, a, b, False)))
                            for r, a, b in zip(robots, cuts, cuts[1:], strict=False))
                best = min(best, worst)
    return int(best)


@settings(max_examples=150, deadline=None)
@given(lines())
def test_the_greedy_on_a_line_is_valid_and_never_beats_brute_force(
        line: tuple[np.ndarray, np.ndarray]) -> None:
    walks, positions = line
    n = walks.shape[1]
    top = int(walks.max() + positions[-1]) + 1  # one robot doing it all always fits
    found = Reach(walks, depth=2, positions=positions).best(0, top + 1, np.zeros(1, int))
    assert found is not None
    bound, stretches = found
    assert bound >= brute_force_line(walks, positions)
    assert [i for s in stretches for i in range(s.first, s.end)] == list(range(n))
    assert len({s.robot for s in stretches}) == len(stretches)
    assert all(line_cost(walks, positions, s) <= bound for s in stretches)


def test_the_greedy_on_a_line_is_mostly_exact() -> None:
    """A heuristic: a check that the look-ahead works on lines too, not a promise of
    optimality (measured on these draws: exact on 60 of 60, 41 without the look-ahead)."""
    rng = np.random.default_rng(11)
    exact = 0
    for _ in range(60):
        n, k = int(rng.integers(4, 9)), int(rng.integers(2, 4))
        positions = np.concatenate([[0], np.cumsum(rng.integers(1, 4, n - 1))])
        at, loads = rng.integers(0, int(positions[-1]) + 1, k), rng.integers(0, 6, k)
        walks = loads[:, None] + np.abs(positions[None, :] - at[:, None])
        found = Reach(walks, depth=2, positions=positions).best(
            0, int(walks.max() + positions[-1]) + 2, np.zeros(1, int))
        assert found is not None
        exact += found[0] == brute_force_line(walks, positions)
    assert exact >= 50
