"""Balanced planner (issue 7, speed follow-up): the shortcuts that replaced plain scans, each
against a fresh computation (cut cells, ring table, neighbour pairs, offers, distances)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.balanced import reshape as reshape_module
from planner.balanced.assign import _lower_distances
from planner.balanced.balance import WHOLE
from planner.balanced.regions import _partition_state
from planner.balanced.relieve import _Offers
from planner.balanced.relocate import cell_distances
from planner.balanced.state import (
    RING,
    RING_REMOVABLE,
    PartitionState,
    articulation_points,
    splits,
)
from planner.grid import WorkArea, expand, label_components, work_area
from planner.placement import random_starts
from planner.types import OccupancyGrid


def _issue_instance(k: int, seed: int) -> WorkArea:
    """The issue's setting (as benchmarks/bench_balanced.py): 20 x 30 cells, 80 blocked."""
    rng = np.random.default_rng(seed)
    coarse = np.ones((20, 30), dtype=bool)
    coarse.ravel()[rng.choice(coarse.size, size=80, replace=False)] = False
    grid = OccupancyGrid(expand(coarse))
    return work_area(grid, random_starts(grid, k, seed))


def _random_nodes(h: int, w: int, seed: int) -> tuple[PartitionState, set[int]]:
    rng = np.random.default_rng(seed)
    state = PartitionState(np.ones((h, w), dtype=bool), [(0, 0)])
    return state, {int(u) for u in np.flatnonzero(rng.random((h, w)) < 0.7)}


def test_ring_table_matches_its_definition() -> None:
    # removable: some side cell of the ring is in the region, and all such side cells are
    # linked through region cells of the ring (3 x 3 block without its centre)
    for mask in range(256):
        block = np.zeros((3, 3), dtype=bool)
        for i, (dr, dc) in enumerate(RING):
            block[1 + dr, 1 + dc] = bool(mask >> i & 1)
        labels, _ = label_components(block)
        sides = {int(labels[1 + dr, 1 + dc]) for dr, dc in RING[1::2] if block[1 + dr, 1 + dc]}
        assert RING_REMOVABLE[mask] == (len(sides) == 1), mask


@settings(max_examples=100, deadline=None)
@given(st.integers(1, 7), st.integers(1, 7), st.integers(0, 10_000))
def test_splits_matches_articulation_points(h: int, w: int, seed: int) -> None:
    state, nodes = _random_nodes(h, w, seed)
    cut = articulation_points(nodes, state.neighbours)
    assert {v for v in nodes if splits(nodes, state.neighbours, v)} == cut


@settings(max_examples=100, deadline=None)
@given(st.integers(1, 7), st.integers(1, 7), st.integers(0, 10_000))
def test_is_cut_matches_articulation_points_as_the_region_changes(h: int, w: int,
                                                                   seed: int) -> None:
    state, nodes = _random_nodes(h, w, seed)
    rng = np.random.default_rng(seed + 1)
    order = sorted(nodes)
    rng.shuffle(order)
    for step, u in enumerate(order):  # grow the region cell by cell, asking each time
        state.claim(0, u)
        cut = articulation_points(state.whole[0], state.neighbours)
        if step % 2:  # the cut cells as cached (some kept up to date by claim)
            assert state.cut_cells(0) == cut
        for v in rng.permutation(sorted(state.whole[0])).tolist():
            assert state.is_cut(0, v) == (v in cut)
    for u in order[: len(order) // 2]:
        state.release(0, u)
        cut = articulation_points(state.whole[0], state.neighbours)
        assert {v for v in state.whole[0] if state.is_cut(0, v)} == cut


def _connected_without_holes(h: int, w: int, nodes: set[int]) -> bool:
    """Brute force: one 4-connected part, and outside it (the grid padded by a free ring)
    one 8-connected part, the one round the border."""
    if not nodes:
        return False
    inside = np.zeros((h + 2, w + 2), dtype=bool)
    for u in nodes:
        inside[1 + u // w, 1 + u % w] = True

    def parts(mask: np.ndarray, steps: list[tuple[int, int]]) -> int:
        seen = np.zeros_like(mask)
        count = 0
        for r, c in zip(*np.nonzero(mask), strict=True):
            if seen[r, c]:
                continue
            count += 1
            seen[r, c] = True
            stack = [(r, c)]
            while stack:
                a, b = stack.pop()
                for dr, dc in steps:
                    x, y = a + dr, b + dc
                    if 0 <= x < h + 2 and 0 <= y < w + 2 and mask[x, y] and not seen[x, y]:
                        seen[x, y] = True
                        stack.append((x, y))
        return count

    sides = [(0, 1), (1, 0), (0, -1), (-1, 0)]
    return parts(inside, sides) == 1 and parts(~inside, sides + list(RING[::2])) == 1


@settings(max_examples=150, deadline=None)
@given(st.integers(1, 7), st.integers(1, 7), st.integers(0, 10_000), st.floats(0.3, 0.95))
def test_hole_free_matches_a_count_of_parts(h: int, w: int, seed: int, fill: float) -> None:
    """The Euler-number test is_cut trusts the local test by (PartitionState.hole_free)."""
    rng = np.random.default_rng(seed)
    state = PartitionState(np.ones((h, w), dtype=bool), [(0, 0)])
    for u in np.flatnonzero(rng.random((h, w)) < fill).tolist():
        state.claim(0, u)
    assert state.hole_free(0) == _connected_without_holes(h, w, state.whole[0])


@pytest.mark.parametrize(("k", "seed"), [(10, 4), (30, 2)])
def test_is_cut_answers_during_balancing_match_a_fresh_computation(
        monkeypatch: pytest.MonkeyPatch, k: int, seed: int) -> None:
    real = PartitionState.is_cut
    asked = []

    def checked(state: PartitionState, robot: int, u: int) -> bool:
        got = real(state, robot, u)
        assert got == (u in articulation_points(state.whole[robot], state.neighbours))
        asked.append(got)
        return got

    monkeypatch.setattr(PartitionState, "is_cut", checked)
    assert _partition_state(_issue_instance(k, seed), seed, None, None) is not None
    assert any(asked) and not all(asked)  # both answers were checked


@settings(max_examples=60, deadline=None)
@given(st.integers(2, 8), st.integers(2, 8), st.integers(0, 10_000), st.integers(1, 6))
def test_lower_distances_match_a_fresh_search(h: int, w: int, seed: int, count: int) -> None:
    state, cells = _random_nodes(h, w, seed)
    if not cells:
        return
    rng = np.random.default_rng(seed)
    sources: list[int] = []
    dist = cell_distances(state, sources, cells)
    for u in rng.choice(sorted(cells), size=min(count, len(cells)), replace=False).tolist():
        sources.append(u)
        _lower_distances(state, dist, u, cells)
        assert dist == cell_distances(state, sources, cells)


@pytest.mark.parametrize(("k", "seed"), [(10, 4), (30, 2)])
def test_neighbour_pairs_and_offers_match_a_plain_scan(k: int, seed: int) -> None:
    state = _partition_state(_issue_instance(k, seed), seed, None, None)
    assert state is not None
    pairs: set[tuple[int, int]] = set()
    offers: dict[int, dict[int, set[int]]] = {}
    for robot in range(state.k):
        for u in state.whole[robot]:
            for v in state.neighbours[u]:
                other = state.label[v]
                if other < 0 or other == robot:
                    continue
                a, b = sorted((robot, other), key=lambda r: (state.load[r], r))
                pairs.add((a, b))
                if state.load[other] + WHOLE < state.load[robot]:
                    offers.setdefault(robot, {}).setdefault(u, set()).add(other)
    assert pairs and reshape_module._neighbour_pairs(state) == sorted(pairs)
    found = _Offers(state)
    assert found.givers == sorted(offers)
    for giver in found.givers:
        pairs_of = found.of(giver)
        assert pairs_of == sorted(pairs_of)
        assert sorted(set(pairs_of)) == sorted((u, y) for u, ys in offers[giver].items()
                                               for y in ys)
        assert found.lowest_taker[giver] == min(state.load[y] for ys in offers[giver].values()
                                                for y in ys)


@settings(max_examples=60, deadline=None)
@given(st.integers(1, 12), st.integers(0, 10_000), st.floats(0.05, 0.6))
def test_perfect_assignment_test_agrees_with_bipartite_matching(n: int, seed: int,
                                                               density: float) -> None:
    """assign._perfect (a 0/1 least-cost assignment) against scipy's maximum matching."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import maximum_bipartite_matching

    from planner.balanced.assign import UNREACHABLE, _perfect

    rng = np.random.default_rng(seed)
    within = rng.random((n, n)) < density
    travel = np.where(rng.random((n, n)) < 0.9, 0, UNREACHABLE)
    allowed = csr_matrix(within & (travel < UNREACHABLE))
    matched = (maximum_bipartite_matching(allowed, perm_type="column") >= 0).all()
    assert _perfect(within, travel) == bool(matched)


def test_seeded_small_kruskal_trees_are_scipys() -> None:
    """Seeded kruskal trees small enough for the plain-Python Kruskal: scipy's tree."""
    from planner import trees

    rng = np.random.default_rng(7)
    checked = 0
    for seed in range(150):
        h, w = (int(x) for x in rng.integers(1, 10, 2))
        cells = rng.random((h, w)) < 0.85
        if label_components(cells)[1] != 1:
            continue
        fast = trees.build_tree(cells, "kruskal", seed=seed)
        small, trees._SMALL_MST = trees._SMALL_MST, -1
        try:
            slow = trees.build_tree(cells, "kruskal", seed=seed)
        finally:
            trees._SMALL_MST = small
        assert (fast.right == slow.right).all() and (fast.down == slow.down).all()
        checked += 1
    assert checked > 50
