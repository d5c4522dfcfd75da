"""Create Tree (paper 000, section 3): spanning, Lemma 2, starts, seeds, bridge selection."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.createtree import create_tree, create_tree_search
from planner.createtree.bridges import bridge_tries, join
from planner.cycle import stc_cycle
from planner.errors import DisconnectedRobotsError, RobotPlacementError
from planner.grid import label_components
from planner.invariants import check_tree
from planner.trees import build_tree
from planner.types import BoolArray, Cell, SpanningTree

MEASURES = ("manhattan", "euclidean", "path")


def connected_instance(seed: int, shape: tuple[int, int], density: float,
                       k: int) -> tuple[BoolArray, list[Cell]]:
    """A random grid's largest component and k distinct start cells in it."""
    rng = np.random.default_rng(seed)
    cells = rng.random(shape) >= density
    labels, count = label_components(cells)
    if count == 0:
        cells = np.ones(shape, dtype=bool)
        labels, count = label_components(cells)
    sizes = np.bincount(labels.ravel())[1:]
    area = labels == int(np.argmax(sizes)) + 1
    free = np.argwhere(area)
    picks = rng.choice(len(free), size=min(k, len(free)), replace=False)
    return area, [(int(free[i][0]), int(free[i][1])) for i in picks]


def oracle_gap(tree: SpanningTree, starts: list[Cell]) -> int:
    """Largest cycle distance between consecutive robots, read off the full STC cycle."""
    cycle = stc_cycle(tree)
    pos = sorted(cycle.position((2 * r, 2 * c)) for r, c in starts)
    gaps = [b - a for a, b in itertools.pairwise(pos)] + [cycle.n - pos[-1] + pos[0]]
    return max(gaps)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), h=st.integers(2, 9), w=st.integers(2, 11),
       density=st.sampled_from([0.0, 0.1, 0.25]), k=st.integers(1, 6),
       measure=st.sampled_from(MEASURES))
def test_result_is_spanning_tree_of_the_component(seed: int, h: int, w: int, density: float,
                                                  k: int, measure: str) -> None:
    cells, starts = connected_instance(seed, (h, w), density, k)
    tree = create_tree(cells, starts, measure=measure, seed=seed)
    check_tree(tree)
    assert np.array_equal(tree.cells, cells)


@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 10_000), h=st.integers(2, 9), w=st.integers(2, 11),
       density=st.sampled_from([0.0, 0.15, 0.3]), k=st.integers(1, 8),
       measure=st.sampled_from(MEASURES))
def test_subtrees_partition_the_area_lemma_2(seed: int, h: int, w: int, density: float, k: int,
                                            measure: str) -> None:
    cells, starts = connected_instance(seed, (h, w), density, k)
    sub, _ = create_tree_search(cells, starts, measure=measure, seed=seed)
    # every reachable cell in exactly one subtree, nothing outside the area
    assert (sub.owner[cells] >= 0).all()
    assert (sub.owner[~cells] == -1).all()
    for i, root in enumerate(sub.roots):
        assert sub.owner[root] == i
        part = sub.owner == i
        forest = SpanningTree(cells=part, right=sub.right & part, down=sub.down & part)
        check_tree(forest)  # each subtree is itself a tree over its own cells
    # no subtree edge crosses between subtrees
    assert not (sub.right[:, :-1] & (sub.owner[:, :-1] != sub.owner[:, 1:])).any()
    assert not (sub.down[:-1, :] & (sub.owner[:-1, :] != sub.owner[1:, :])).any()
    for cell in starts:
        assert sub.roots[sub.owner[cell]] == cell


def test_deterministic_per_seed() -> None:
    cells, starts = connected_instance(7, (12, 16), 0.15, 6)
    a = create_tree(cells, starts, seed=11)
    b = create_tree(cells, starts, seed=11)
    assert np.array_equal(a.right, b.right) and np.array_equal(a.down, b.down)


@pytest.mark.parametrize("measure", MEASURES)
def test_chosen_bridge_set_is_best_of_those_tried(measure: str) -> None:
    cells, starts = connected_instance(3, (10, 14), 0.1, 7)
    sub, search = create_tree_search(cells, starts, measure=measure, alpha=2.0, seed=5)
    assert len(search.scores) == bridge_tries(len(starts), int(cells.sum()), 2.0)
    # the batched scores are the real cycle gaps (oracle: build each tree's full cycle)
    for i in [*list(range(0, len(search.scores), 17)), search.best]:
        tree = join(sub, search.bridges[i])
        check_tree(tree)
        assert search.scores[i] == oracle_gap(tree, starts)
    assert search.scores[search.best] == search.scores.min()
    chosen = create_tree(cells, starts, measure=measure, alpha=2.0, seed=5)
    assert oracle_gap(chosen, starts) <= search.scores.min()


def test_bridge_count_rule() -> None:
    # Alg. 1 line 12 and section 3.3.1: max{k^alpha, N}
    assert bridge_tries(30, 600, 2.0) == 900
    assert bridge_tries(30, 600, 1.0) == 600
    assert bridge_tries(10, 600, 3.0) == 1000
    assert bridge_tries(1, 600, 2.0) == 1
    # the prose's k^alpha
    assert bridge_tries(30, 600, 1.0, rule="power") == 30
    assert bridge_tries(5, 600, 2.0, rule="power") == 25
    cells, starts = connected_instance(4, (6, 8), 0.0, 5)
    _, search = create_tree_search(cells, starts, alpha=2.0, rule="power")
    assert len(search.scores) == 25


def test_spreads_robots_better_than_random_trees() -> None:
    """The point of Create Tree: a smaller largest gap than uniformly random trees."""
    ours, theirs = [], []
    for seed in range(6):
        cells, starts = connected_instance(100 + seed, (10, 15), 0.1, 8)
        ours.append(oracle_gap(create_tree(cells, starts, seed=seed), starts))
        theirs.append(oracle_gap(build_tree(cells, "random", seed=seed), starts))
    assert np.mean(ours) < np.mean(theirs)


def test_disconnected_starts_are_rejected() -> None:
    cells = np.ones((4, 5), dtype=bool)
    cells[:, 2] = False
    with pytest.raises(DisconnectedRobotsError):
        create_tree(cells, [(0, 0), (0, 4)])


def test_start_on_obstacle_is_rejected() -> None:
    cells = np.ones((4, 5), dtype=bool)
    cells[1, 1] = False
    with pytest.raises(RobotPlacementError):
        create_tree(cells, [(1, 1)])


def test_shared_start_cell_gives_one_subtree() -> None:
    cells = np.ones((5, 6), dtype=bool)
    sub, _ = create_tree_search(cells, [(2, 2), (2, 2), (0, 0)],
                                start_subcells=[(4, 4), (5, 5), (0, 0)])
    assert sub.k == 2
    check_tree(create_tree(cells, [(2, 2), (2, 2), (0, 0)]))


@pytest.mark.parametrize("seed", range(8))
def test_hilling_stretches_a_corridor_into_one_path(seed: int) -> None:
    """One robot at the end of a 2-wide corridor: wherever its main branch gets stuck, hills
    (two side cells at a time) absorb the rest, so the subtree is a single path; a breadth-
    first branch-out would leave cells of degree 3."""
    cells = np.ones((2, 9), dtype=bool)
    tree = create_tree(cells, [(0, 0)], seed=seed)
    check_tree(tree)
    degree = np.zeros(cells.shape, dtype=int)
    degree[:, :-1] += tree.right[:, :-1]
    degree[:, 1:] += tree.right[:, :-1]
    degree[:-1, :] += tree.down[:-1, :]
    degree[1:, :] += tree.down[:-1, :]
    assert degree.max() <= 2
    assert degree[0, 0] == 1
