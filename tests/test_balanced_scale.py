"""The balanced planner's large-k paths (issue 14, item 4): many robots on city maps.

From 49 robots the Voronoi owners come from a multi-source Dijkstra, the relieve move makes
many disjoint hand-overs per scan and the relocation tries / assignment rounds are bounded
by robot budgets (docs/balanced.md, "Planning at scale"); these tests check that such
plans keep every promise of the small ones. Timing goals live in
benchmarks/bench_balanced_scale.py, not here.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from balanced_helpers import check_regions, relaxed

from planner.balanced import balanced_plan, partition
from planner.balanced.growth import seed_regions
from planner.balanced.plan import better_than_opt
from planner.balanced.state import PartitionState
from planner.balanced.voronoi import MANY, _distances, _Owners
from planner.geometry import cell_of
from planner.grid import work_area
from planner.invariants import check_plan
from planner.maps.city import city_grid
from planner.offline.plan import make_plan
from planner.placement import random_starts
from planner.trees import build_tree


@pytest.mark.parametrize(("size", "k", "seed"), [(128, 120, 1), (128, 200, 2), (96, 100, 3)])
def test_many_robots_get_a_valid_plan_never_worse_than_opt(size: int, k: int,
                                                           seed: int) -> None:
    grid = city_grid(size, seed)
    area = work_area(grid, random_starts(grid, k, seed))
    plan = balanced_plan(area, seed=seed)
    assert plan.k == k and plan.makespan >= math.ceil(area.n / k) - 1
    if relaxed(plan.notes):
        check_plan(plan, area, max_visits=k + 1, own_revisits_only=False)
    else:
        check_plan(plan, area)  # every sub-cell exactly once, by one robot
    parts = partition(area, seed=seed)
    assert parts is not None
    check_regions(parts, area.cells, area.starts)  # connected, tiling, leaves anchored
    assert sum(parts.sizes) == area.n
    tree = build_tree(area.cells, "dfs", seed=seed, starts=[cell_of(s) for s in area.starts])
    kept = better_than_opt(plan, area, tree)  # what the registry's plan_for returns
    assert kept.makespan == min(plan.makespan, make_plan(area, tree, "opt").makespan)


@pytest.mark.slow  # 3-4 s of CPU alone (the quick loop stays near a minute)
def test_many_robot_plans_are_the_same_for_the_same_seed() -> None:
    grid = city_grid(96, 4)
    area = work_area(grid, random_starts(grid, 80, 4))
    first, second = balanced_plan(area, seed=4), balanced_plan(area, seed=4)
    assert [rp.path for rp in first.robots] == [rp.path for rp in second.robots]


@pytest.mark.parametrize("seed", range(3))
def test_dijkstra_owners_equal_the_dense_argmin(seed: int) -> None:
    """_Owners (many robots) against dist + weight argmin over the full k x N table, with
    ties (all weights 0, integer weights) going to the lowest robot there too."""
    grid = city_grid(96, seed)
    area = work_area(grid, random_starts(grid, 2 * MANY + 10, seed))
    state = PartitionState(area.cells, area.starts)
    seed_regions(state)
    robots = [r for r in range(state.k) if state.whole[r]]
    cells = [u for u, lab in enumerate(state.label) if state.free[u] and lab >= -1]
    seeds = [min(state.whole[r]) for r in robots]
    owners = _Owners(state, cells, seeds)
    dist = _distances(state, cells, seeds)
    dense = dist[:, owners.reach].T.astype(np.float64)
    rng = np.random.default_rng(seed)
    trials = [np.zeros(len(robots)), rng.integers(-5, 6, len(robots)).astype(np.float64)]
    trials += [rng.normal(0.0, scale, len(robots)) for scale in (3.0, 30.0)]
    for weights in trials:
        assert (owners.argmin(weights) == (dense + weights).argmin(axis=1)).all()
