"""NCOCTA / COCTA: connectivity (Lemma 4.1), completion (Lemma 4.2), Lemma 4.3's closed form,
the paper's worked example under both clocks (edge steps, loop iterations), theorem bounds."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from treecover_helpers import ALGOS, random_trees

from planner.errors import PlannerError
from planner.treecover.loop import run_loop_iterations
from planner.treecover.rules import split_need
from planner.treecover.sim import default_splits, run_coverage
from planner.treecover.splits import (
    consecutive,
    guaranteed_speedup,
    lemma44_bound,
    ncocta_splits,
    ncocta_time,
    paper_m,
    robots_needed,
)
from planner.treecover.state import CoverageState
from planner.treecover.step import decide
from planner.treecover.trees import general_tree, office_tree, perfect_tree
from planner.treecover.types import Algo, Splits


def _check_run(tree, robots: int, algo: str, splits: Splits | None = None):  # type: ignore[no-untyped-def]
    result = run_coverage(tree, robots, algo, splits)
    assert result.connected
    assert np.all(result.visit_time >= 0)  # every node visited
    # all robots return to the root: every edge walked down and up, k walks per step
    assert result.time * robots >= 2 * (tree.n - 1)
    assert result.time >= 2 * tree.height
    assert result.explore_time <= result.time
    return result


@settings(max_examples=60, deadline=None)
@given(tree=random_trees(), robots=st.integers(1, 30), algo=st.sampled_from(ALGOS))
def test_random_trees_stay_connected_and_finish(tree, robots: int, algo: str) -> None:  # type: ignore[no-untyped-def]
    _check_run(tree, robots, algo)


@settings(max_examples=40, deadline=None)
@given(tree=random_trees(), data=st.data(), algo=st.sampled_from(ALGOS))
def test_random_splits_with_enough_robots(tree, data, algo: str) -> None:  # type: ignore[no-untyped-def]
    if tree.height < 1:
        return
    heights = data.draw(st.lists(st.integers(1, tree.height), min_size=1, max_size=3,
                                 unique=True))
    splits = Splits(tuple(sorted(heights, reverse=True)))
    branching = int(np.diff(tree.child_start).max())
    extra = data.draw(st.integers(0, 4))
    _check_run(tree, robots_needed(branching, splits) + extra, algo, splits)


@pytest.mark.parametrize("algo", ALGOS)
def test_one_robot_is_a_depth_first_search(algo: str) -> None:
    tree = perfect_tree(3, 3)
    result = _check_run(tree, 1, algo)
    assert result.time == 2 * (tree.n - 1)
    assert result.speedup == 1.0


@pytest.mark.parametrize(("n", "hm"), [(2, 1), (2, 3), (2, 5), (3, 2), (3, 4), (4, 3)])
def test_lemma_4_3_closed_form(n: int, hm: int) -> None:
    """A subtree of height h_m explored by N h_m + 1 robots takes (N^h_m - 1)/(N - 1) + h_m."""
    tree = perfect_tree(n, hm)
    result = _check_run(tree, n * hm + 1, "ncocta", Splits((hm,)))
    assert result.time == (n ** hm - 1) // (n - 1) + hm


@pytest.mark.parametrize(("n", "h", "heights"), [
    (2, 3, (3, 2)), (2, 6, (4,)), (2, 9, (6, 5, 4)), (2, 7, (5, 4, 3)), (2, 8, (6, 3)),
    (3, 5, (4, 3)),
    (3, 6, (3,)), (4, 4, (3, 2)),
])
def test_simulator_matches_recursive_closed_form(n: int, h: int,
                                                 heights: tuple[int, ...]) -> None:
    splits = Splits(heights)
    tree = perfect_tree(n, h)
    result = _check_run(tree, robots_needed(n, splits), "ncocta", splits)
    gaps = np.diff(heights)
    if np.all(gaps == -1):  # the consecutive splits the paper analyses: exact
        assert result.time == ncocta_time(n, h, splits)
    else:  # wider gaps: the trail runs ahead of the team, so the recursion is an upper bound
        assert result.time <= ncocta_time(n, h, splits)


def test_figure_1_example_team_size() -> None:
    assert robots_needed(2, Splits((3, 2))) == 11  # k = 1 + 2*3 + 2*2


def test_worked_example_3ary_height_7() -> None:
    """Sec. 4.2: 16 robots on a 3-ary tree of height 7: m = 1, guaranteed SF 2*3 - 1 = 5."""
    assert paper_m(16, 3) == 1
    assert paper_m(15, 3) == 0
    splits = ncocta_splits(16, 3, 7)
    assert splits == Splits((5,))
    assert guaranteed_speedup(3, splits.m) == 5
    tree = perfect_tree(3, 7)
    ncocta = _check_run(tree, 16, "ncocta")
    assert 5 < ncocta.speedup < 6  # Lemmas 4.5 and 4.6: 2N^m - 1 < SF < 2N^m
    assert ncocta.speedup > lemma44_bound(3, splits)
    cocta = _check_run(tree, 20, "cocta")
    assert cocta.speedup > 7 > ncocta.speedup  # four more robots help COCTA
    assert run_coverage(tree, 20, "ncocta").speedup < 6  # ... but not NCOCTA


def test_worked_example_counted_in_loop_iterations() -> None:
    """Sec. 4.3's 'speedup ... increases to 8.6' with 20 robots comes out when time counts
    iterations of Algorithm 2's in-place loop; NCOCTA keeps Lemmas 4.5 / 4.6 either way."""
    tree = perfect_tree(3, 7)
    cocta = _check_loop_run(tree, 20, "cocta")
    assert abs(cocta.speedup - 8.6) < 0.1
    assert cocta.time < run_coverage(tree, 20, "cocta").time  # robots climb several edges
    ncocta = _check_loop_run(tree, 16, "ncocta")
    assert 5 < ncocta.speedup < 6


def _check_loop_run(tree, robots: int, algo: str):  # type: ignore[no-untyped-def]
    result = run_loop_iterations(tree, robots, algo)
    assert result.connected
    assert np.all(result.visit_time >= 0)
    assert result.time >= tree.height  # one edge down per iteration at most
    assert result.explore_time <= result.time
    return result


@settings(max_examples=40, deadline=None)
@given(tree=random_trees(), robots=st.integers(1, 30), algo=st.sampled_from(ALGOS))
def test_loop_iterations_stay_connected_and_finish(tree, robots: int, algo: str) -> None:  # type: ignore[no-untyped-def]
    result = _check_loop_run(tree, robots, algo)
    assert result.time <= run_coverage(tree, robots, algo).time


def _not_finished_brute_force(state: CoverageState, v: int) -> int:
    """Count nodes w of T_v with unexplored nodes at or below w or robots strictly below w."""
    stack, count = [v], 0
    while stack:
        w = stack.pop()
        stack.extend(state.children[w])
        if state.unexplored[w] > 0 or state.sub[w] > state.at.get(w, 0):
            count += 1
    return count


@settings(max_examples=30, deadline=None)
@given(tree=random_trees(), robots=st.integers(2, 12))
def test_not_finished_counts_match_brute_force(tree, robots: int) -> None:  # type: ignore[no-untyped-def]
    """COCTA's cap (sec. 4.3: nodes of the subtree that are not finished), kept incrementally."""
    splits = default_splits(tree, robots, Algo.COCTA)
    state = CoverageState(tree, robots)
    state.need = split_need(state, splits)
    while not state.done():
        for v in range(tree.n):
            assert state.not_finished(v) == _not_finished_brute_force(state, v)
        state.apply(decide(state, Algo.COCTA, splits))


def test_58_robots_make_a_second_split() -> None:
    """'The speedup remains less than 6 until the number of robots is 58, when it becomes 17'."""
    assert paper_m(57, 3) == 1
    assert paper_m(58, 3) == 2
    assert guaranteed_speedup(3, 2) == 17
    splits = ncocta_splits(58, 3, 8)
    result = _check_run(perfect_tree(3, 8), 58, "ncocta")
    assert result.splits == splits
    assert 17 < result.speedup < 18


@pytest.mark.parametrize(("n", "h", "robots"), [(2, 8, 20), (3, 5, 25), (2, 9, 40)])
def test_cocta_not_worse_than_ncocta_with_same_splits(n: int, h: int, robots: int) -> None:
    tree = perfect_tree(n, h)
    ncocta = _check_run(tree, robots, "ncocta")
    cocta = _check_run(tree, robots, "cocta", ncocta.splits)
    assert cocta.time <= ncocta.time


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_cocta_on_general_trees(seed: int) -> None:
    tree = general_tree(2, 8, remove=6, at_height=3, seed=seed)
    _check_run(tree, 30, "cocta")


def test_office_tree_runs() -> None:
    tree = office_tree()
    for robots in (1, 3, 4, 10):
        for algo in ALGOS:
            _check_run(tree, robots, algo)


def test_consecutive_splits() -> None:
    assert consecutive(5, 3).heights == (7, 6, 5)
    with pytest.raises(ValueError):
        Splits((3, 3))


def test_zero_robots_is_a_user_error() -> None:
    with pytest.raises(PlannerError):
        run_coverage(perfect_tree(2, 2), 0, "cocta")
