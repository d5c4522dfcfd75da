"""Balanced planner (issue 7): valid, non-redundant plans; balance; shared start cells; takeover."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np
import pytest
from balanced_helpers import (
    check_balanced,
    check_regions,
    crowded,
    grid_of,
    instances,
    relaxed,
)
from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st

from planner.algorithms import algorithm
from planner.balanced import balanced_plan, partition
from planner.balanced.coverage import region_path
from planner.balanced.plan import OPT_KEPT, SPLIT, WALK_OUT
from planner.balanced.seeds import open_walk_ok, share_cell
from planner.balanced.takeover import simulate_failures
from planner.errors import UnsupportedPlanError
from planner.experiments.instances import maze_cells
from planner.geometry import cell_of, sub_cells_of
from planner.grid import expand, label_components, work_area
from planner.invariants import check_coverage, check_path_moves, check_plan
from planner.offline.plan import make_plan
from planner.placement import random_starts
from planner.trees import build_tree
from planner.types import OccupancyGrid, SubCell


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances())
def test_plans_cover_every_sub_cell_once(case: tuple[OccupancyGrid, tuple[SubCell, ...], int]
                                         ) -> None:
    check_balanced(*case)


@settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(crowded())
def test_robots_sharing_start_cells(case: tuple[OccupancyGrid, tuple[SubCell, ...], int]) -> None:
    check_balanced(*case)


@pytest.mark.parametrize("starts", [
    ((0, 0), (1, 0)), ((0, 0), (0, 1)), ((0, 0), (1, 1)), ((0, 1), (1, 0)),
    ((0, 0), (1, 0), (0, 1)), ((0, 0), (1, 0), (0, 1), (1, 1)),
])
@pytest.mark.parametrize("rows", [["."], [".."], ["..."], [".", "."], ["...", "#.#"],
                                  [".#", ".."]])
def test_shared_cell_in_corners_and_corridors(rows: list[str],
                                              starts: tuple[SubCell, ...]) -> None:
    check_balanced(grid_of(rows), starts, 0)


def test_dead_end_pair_gets_the_corridor() -> None:
    # Robots in the near half of a dead end of a corridor: anchoring at the only open side
    # needs the robot whose part is a run next to the anchor; both halves cannot anchor.
    area = work_area(grid_of(["....."]), ((0, 8), (1, 8)))
    parts = partition(area, seed=0)
    assert parts is not None
    check_regions(parts, area.cells, area.starts)
    for region in parts.regions:  # each robot's walk covers its region once, from its start
        path = region_path(region, seed=0)
        check_path_moves(path)
        assert path[0] == region.start and len(set(path)) == len(path) == region.size
    # Walking along a corridor costs half of covering it (2 moves a cell against 4), so the
    # plan sends robot 1 past robot 0's part instead: regions 3 and 17 give 16 moves, the
    # walk gives 12 (robot 1: 5 moves out, then 8 sub-cells; robot 0: 12 sub-cells).
    plan = balanced_plan(area, seed=0)
    check_plan(plan, area, max_visits=3, own_revisits_only=False)
    assert max(parts.sizes) - 1 == 16
    assert plan.makespan == 12


def test_robot_boxed_in_a_dead_end_walks_out() -> None:
    # Robot 0 starts in a one-cell dead end whose only exit is robot 1's start cell: no
    # connected region holding robot 0's start can have more than that cell.
    grid = grid_of(["#.#######", ".........", "........."])
    area = work_area(grid, ((1, 2), (2, 2)))
    bound = math.ceil(area.n / 2) - 1
    plan = balanced_plan(area, seed=0)
    assert any(note.startswith(WALK_OUT) for note in plan.notes)
    check_plan(plan, area, max_visits=2, own_revisits_only=False)
    stuck = partition(area, seed=0)
    assert stuck is not None and min(stuck.sizes) == 4  # without walking out: 4 vs 72
    # Against what it replaces, not a measured margin: robot 1 alone on 72 sub-cells needs 71
    # moves. Two moves out (through robot 1's start cell), then regions balanced with that in
    # mind, come within a few moves of the bound — but plain opt reaches the bound here, so
    # the registry's planner (the better of the two) must be optimal.
    assert bound <= plan.makespan < max(stuck.sizes) - 1
    tree = build_tree(area.cells, "dfs", seed=0)
    registry = algorithm("balanced").load_plan()(area, tree, "balanced", 0)
    assert make_plan(area, tree, "opt").makespan == bound == registry.makespan
    result = simulate_failures(plan, {0: 1}, recovery="takeover")
    assert result.complete


def test_open_walk_rule_matches_brute_force() -> None:
    """open_walk_ok agrees with a search for a Hamiltonian path on the real sub-cell graph."""
    cell = (1, 1)
    subs = sub_cells_of(cell)
    for side in [(0, -1), (0, 1), (-1, 0), (1, 0), None]:
        anchor = None if side is None else (2 * (1 + side[0]), 2 * (1 + side[1]))
        for size in range(1, 5):
            for keep in itertools.combinations(subs, size):
                for start in keep:
                    got = open_walk_ok(cell, side, set(keep), start)
                    assert got == _hamiltonian_from(start, set(keep), anchor, side), \
                        (side, keep, start)


def _hamiltonian_from(start: SubCell, keep: set[SubCell], anchor: SubCell | None,
                      side: tuple[int, int] | None) -> bool:
    """Brute force: an open walk from start over keep plus, when anchored, the neighbour cell.

    The neighbour cell stands for the rest of the region; the walk must enter and leave it
    only through its two sub-cells next to the leaf (the STC walk of the tree beyond).
    """
    nodes = set(keep)
    if anchor is not None and side is not None:
        ar, ac = anchor
        nodes |= set(sub_cells_of((ar // 2, ac // 2)))
    for order in itertools.permutations(sorted(nodes - {start})):
        path = [start, *order]
        if all(abs(a[0] - b[0]) + abs(a[1] - b[1]) == 1 for a, b in itertools.pairwise(path)):
            return True
    return False


def _optimum_whole_cells(area_cells: np.ndarray, starts: Sequence[SubCell]) -> int:
    """Smallest possible largest region (cells) over all connected whole-cell partitions."""
    cells = [tuple(int(x) for x in rc) for rc in np.argwhere(area_cells)]
    k = len(starts)
    home = [(r // 2, c // 2) for r, c in starts]
    best = math.inf
    for owners in itertools.product(range(k), repeat=len(cells)):
        assign = dict(zip(cells, owners, strict=True))
        if any(assign[home[i]] != i for i in range(k)):
            continue
        worst = max(owners.count(i) for i in range(k))
        if worst >= best:
            continue
        ok = True
        for i in range(k):
            mask = np.zeros(area_cells.shape, dtype=bool)
            for cell, o in assign.items():
                if o == i:
                    mask[cell] = True
            ok = ok and label_components(mask)[1] == 1
        if ok:
            best = worst
    return int(best)


@st.composite
def tiny_one_robot_per_cell(draw: st.DrawFn
                            ) -> tuple[OccupancyGrid, tuple[SubCell, ...], int]:
    """2 to 3 robots, each in a cell of its own, on a connected map of 2 to 8 cells: the
    cases the whole-cell oracle can search (drawing any instance and skipping the rest
    skipped 47 % of them, and half of what was left had one robot)."""
    seed = draw(st.integers(0, 10_000))
    coarse = np.random.default_rng(seed).random(
        (draw(st.integers(1, 3)), draw(st.integers(2, 3)))) >= draw(st.sampled_from([0.0, 0.2]))
    labels, count = label_components(coarse)
    assume(count >= 1)
    biggest = 1 + int(np.argmax(np.bincount(labels.ravel())[1:]))
    cells = [(int(r), int(c)) for r, c in np.argwhere(labels == biggest)]
    assume(2 <= len(cells) <= 8)
    chosen = draw(st.lists(st.sampled_from(cells), min_size=2, max_size=min(3, len(cells)),
                           unique=True))
    starts = tuple(sub_cells_of(cell)[draw(st.integers(0, 3))] for cell in chosen)
    return OccupancyGrid(expand(labels == biggest)), starts, seed


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(tiny_one_robot_per_cell())
def test_balance_matches_brute_force_on_tiny_maps(
        case: tuple[OccupancyGrid, tuple[SubCell, ...], int]) -> None:
    grid, starts, seed = case
    area = work_area(grid, starts)
    event(f"k = {len(starts)}, {area.cell_count} cells")
    parts = partition(area, seed=seed)
    assert parts is not None
    assert max(parts.sizes) <= 4 * _optimum_whole_cells(area.cells, starts)


@pytest.mark.parametrize("k", [2, 3, 5, 8])
@pytest.mark.parametrize("seed", range(4))
def test_open_rectangle_within_four_moves_of_the_bound(k: int, seed: int) -> None:
    """The issue's hard limit: makespan <= LB + 4 where no obstacle boxes a robot in."""
    grid = OccupancyGrid(np.ones((16, 20), dtype=bool))
    area = work_area(grid, random_starts(grid, k, seed))
    plan = balanced_plan(area, seed=seed)
    bound = math.ceil(area.n / k) - 1
    assert bound <= plan.makespan <= bound + 4


def test_same_seed_same_plan() -> None:
    grid = OccupancyGrid(expand(np.random.default_rng(3).random((9, 11)) > 0.2))
    area = work_area(grid, random_starts(grid, 6, 3))
    a, b = balanced_plan(area, seed=5), balanced_plan(area, seed=5)
    assert [rp.path for rp in a.robots] == [rp.path for rp in b.robots]


# --- takeover --------------------------------------------------------------------------


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(max_side=6, max_k=6), st.data())
def test_takeover_covers_everything_with_up_to_k_minus_1_failures(
        case: tuple[OccupancyGrid, tuple[SubCell, ...], int], data: st.DataObject) -> None:
    grid, starts, seed = case
    area = work_area(grid, starts)
    plan = balanced_plan(area, seed=seed)
    k = plan.k
    dead = data.draw(st.lists(st.integers(0, k - 1), unique=True, max_size=k - 1))
    horizon = plan.makespan + 3
    failures = {r: data.draw(st.integers(0, horizon)) for r in dead}
    delay = data.draw(st.integers(0, 4))
    result = simulate_failures(plan, failures, detection_delay=delay, recovery="takeover")
    assert result.complete
    check_coverage(result.covered, area)
    for robot, walk in zip(result.robots, result.walks, strict=True):
        check_path_moves(walk)
        assert walk[0] == plan.robots[robot].start
        if robot in failures:
            assert len(walk) - 1 <= failures[robot]
    assert {t.dead for t in result.takeovers} <= set(failures)
    assert result.coverage_time is not None
    # k robots visit at most k new sub-cells per step (a takeover walk may cross live
    # robots' regions, so finishing before the failure-free makespan is possible)
    assert result.coverage_time >= math.ceil(area.n / k) - 1


@pytest.mark.slow
@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(max_side=6, max_k=6))
def test_takeover_without_failures_is_the_plan(
        case: tuple[OccupancyGrid, tuple[SubCell, ...], int]) -> None:
    grid, starts, seed = case
    area = work_area(grid, starts)
    plan = balanced_plan(area, seed=seed)
    result = simulate_failures(plan, {}, recovery="takeover")
    assert result.walks == tuple(rp.path for rp in plan.robots)
    assert result.takeovers == ()
    assert result.coverage_time is not None
    if relaxed(plan.notes):
        # A walk to a region elsewhere may cross cells of that region, which its robot then
        # covers again at the end: everything is covered by the makespan, possibly earlier.
        assert result.coverage_time <= plan.makespan
    else:
        assert result.coverage_time == plan.makespan
        assert int(result.visits.max()) == 1


def test_takeover_of_a_robot_dead_at_start_walks_its_whole_region() -> None:
    grid = OccupancyGrid(np.ones((4, 8), dtype=bool))
    area = work_area(grid, ((0, 0), (0, 7)))
    plan = balanced_plan(area, seed=0)
    result = simulate_failures(plan, {1: 0}, recovery="takeover")
    assert result.complete
    survivor = result.walks[0]
    left = plan.robots[1].path[1:]  # the dead robot covered only its start
    assert set(left) <= set(survivor)
    # Own walk, then (no obstacles: shortest = Manhattan) to the nearer end of what is
    # left, then along it.
    end = plan.robots[0].path[-1]
    travel = min(abs(end[0] - s[0]) + abs(end[1] - s[1]) for s in (left[0], left[-1]))
    assert len(survivor) - 1 == plan.robots[0].steps + travel + len(left) - 1


def test_takeover_rejects_bad_failures() -> None:
    grid = OccupancyGrid(np.ones((4, 4), dtype=bool))
    plan = balanced_plan(work_area(grid, ((0, 0), (3, 3))), seed=0)
    with pytest.raises(UnsupportedPlanError, match="no such robot"):
        simulate_failures(plan, {5: 1}, recovery="takeover")
    with pytest.raises(UnsupportedPlanError, match=">= 0"):
        simulate_failures(plan, {0: -1}, recovery="takeover")
    with pytest.raises(UnsupportedPlanError, match="negative"):
        simulate_failures(plan, {}, detection_delay=-1, recovery="takeover")


def test_shared_cell_division_is_always_found() -> None:
    cell = (1, 1)
    subs = sub_cells_of(cell)
    for count in (2, 3, 4):
        for chosen in itertools.combinations(subs, count):
            share = share_cell(cell, list(range(count)), list(chosen), lambda _: False)
            kept = [s for _, keep, _ in share.parts for s in keep]
            assert sorted(kept) == sorted(subs)


@pytest.mark.parametrize("seed", range(6))
def test_the_registrys_balanced_plan_is_never_worse_than_opt_on_the_same_tree(seed: int) -> None:
    """Mazes (one-cell corridors) are where balanced regions lose to plain opt: the
    registry's planner then keeps opt's plan, which the balanced robots replay too."""
    rng = np.random.default_rng(seed)
    grid = OccupancyGrid(expand(maze_cells(6, 9, rng)))
    area = work_area(grid, random_starts(grid, 8, seed))
    tree = build_tree(area.cells, "dfs", seed=seed, starts=[cell_of(s) for s in area.starts])
    plan = algorithm("balanced").load_plan()(area, tree, "balanced", seed)
    opt = make_plan(area, tree, "opt")
    assert plan.algo == "balanced" and plan.makespan <= opt.makespan
    best_of_two = min(opt.makespan, balanced_plan(area, seed=seed).makespan)
    # the cycle split (tests/test_balanced_split.py) is kept only when it is shorter still
    assert plan.makespan == best_of_two or (plan.notes[0].startswith(SPLIT)
                                            and plan.makespan < best_of_two)
    if plan.notes[0].startswith(OPT_KEPT):
        assert [rp.path for rp in plan.robots] == [rp.path for rp in opt.robots]
    result = simulate_failures(plan, {plan.robots[1].robot: 9}, detection_delay=1,
                               recovery="takeover")
    assert result.complete
