"""build_plan and make_plan on real STC cycles from real spanning trees."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from oracles import bfs_tree, brute_force_opt, random_cells

from planner.allocation import allocate
from planner.cycle import stc_cycle
from planner.errors import RobotPlacementError
from planner.grid import WorkArea, expand, work_area
from planner.invariants import check_plan
from planner.offline.build import build_plan
from planner.offline.plan import make_plan
from planner.types import OccupancyGrid, SpanningTree, SubCell


def random_area(seed: int, shape: tuple[int, int], k: int,
                obstacles: float = 0.25) -> tuple[WorkArea, SpanningTree]:
    rng = np.random.default_rng(seed)
    cells = random_cells(rng, shape, obstacles)
    subs = np.argwhere(expand(cells))
    k = min(k, len(subs))
    starts: list[SubCell] = [(int(r), int(c))
                             for r, c in subs[rng.choice(len(subs), k, replace=False)]]
    area = work_area(OccupancyGrid(expand(cells)), starts)
    return area, bfs_tree(area.cells)


@settings(max_examples=40, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 6), st.sampled_from(["nb", "bt", "opt"]),
       st.tuples(st.integers(1, 7), st.integers(1, 7)))
def test_make_plan_covers_the_area_with_adjacent_moves(seed: int, k: int, algo: str,
                                                       shape: tuple[int, int]) -> None:
    area, tree = random_area(seed, shape, k)
    plan = make_plan(area, tree, algo)
    # nb never revisits; backtracking walks pass their own cells (and start) twice at most
    check_plan(plan, area, max_visits=1 if algo == "nb" else 2)
    assert plan.n == area.n and plan.k == len(area.starts)
    # Alg. 1: the cycle begins at robot 0's start
    assert plan.cycle.at(0) == area.starts[0] and plan.robots[0].start_index == 0
    for rp in plan.robots:
        assert rp.steps == sum(leg.length for leg in rp.legs)


@settings(max_examples=25, deadline=None)
@given(st.integers(0, 10_000), st.integers(1, 3))
def test_make_plan_opt_is_optimal_on_small_maps(seed: int, k: int) -> None:
    area, tree = random_area(seed, (3, 2), k, obstacles=0.0)
    plan = make_plan(area, tree, "opt")
    positions = [plan.cycle.position(s) for s in area.starts]
    assert plan.makespan == brute_force_opt(plan.n, positions)


def test_make_plan_heterogeneous_speeds_reach_the_plan() -> None:
    area, tree = random_area(7, (5, 5), 3, obstacles=0.0)
    speeds = [1.0, 2.0, 0.5]
    plan = make_plan(area, tree, "opt", speeds=speeds)
    check_plan(plan, area, max_visits=2)
    assert [rp.speed for rp in plan.robots] == speeds
    positions = [plan.cycle.position(s) for s in area.starts]
    expected = max(a.steps / speeds[a.robot]
                   for a in allocate("opt", plan.n, positions, speeds=speeds))
    assert plan.makespan_time == pytest.approx(expected)


def test_make_plan_with_the_project_trees() -> None:
    trees = pytest.importorskip("planner.trees")
    area, _ = random_area(3, (6, 6), 4)
    for kind in trees.TREE_KINDS:
        tree = trees.build_tree(area.cells, kind, seed=1)
        check_plan(make_plan(area, tree, "opt"), area, max_visits=2)


def test_build_plan_rejects_allocations_for_other_starts() -> None:
    area, tree = random_area(11, (4, 4), 2, obstacles=0.0)
    cycle = stc_cycle(tree, start=area.starts[0])
    positions = [cycle.position(s) for s in area.starts]
    allocations = allocate("nb", cycle.n, positions)
    wrong = (area.starts[1], area.starts[0])
    with pytest.raises(RobotPlacementError, match="robot 0 starts at"):
        build_plan("nb", cycle, wrong, allocations)


def test_build_plan_paths_follow_the_legs() -> None:
    area, tree = random_area(5, (4, 5), 3, obstacles=0.0)
    cycle = stc_cycle(tree, start=area.starts[0])
    positions = [cycle.position(s) for s in area.starts]
    allocations = allocate("bt", cycle.n, positions)
    plan = build_plan("bt", cycle, area.starts, allocations, tree=tree)
    for rp, a in zip(plan.robots, allocations, strict=True):
        index = [cycle.position(s) for s in rp.path]
        assert index[0] == a.start_index
        at = 0
        for leg in a.legs:  # each leg is a straight run of +-1 index steps
            for step in range(1, leg.length + 1):
                assert (index[at + step] - index[at + step - 1]) % cycle.n == \
                    leg.direction.sign % cycle.n
            at += leg.length
        assert at == len(index) - 1
    assert plan.tree is tree


def test_make_plan_rejects_a_tree_of_other_cells() -> None:
    area, _ = random_area(2, (4, 4), 2, obstacles=0.0)
    other = area.cells.copy()
    other[np.argwhere(other)[-1][0], np.argwhere(other)[-1][1]] = False
    with pytest.raises(ValueError, match="does not span"):
        make_plan(area, bfs_tree(other), "opt")
