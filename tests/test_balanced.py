"""Balanced planner (issue 7): valid, non-redundant plans; balance; shared start cells; takeover."""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from planner.balanced import Partition, balanced_plan, partition
from planner.balanced.plan import FALLBACK, WALK_OUT
from planner.balanced.regions import _partition_state
from planner.balanced.relocate import relocation_routes
from planner.balanced.seeds import open_walk_ok, share_cell
from planner.balanced.takeover import simulate_failures
from planner.errors import UnsupportedPlanError
from planner.grid import WorkArea, expand, label_components, sub_cells_of, work_area
from planner.invariants import check_coverage, check_path_moves, check_plan
from planner.placement import random_starts
from planner.types import OccupancyGrid, SubCell


def relaxed(plan_notes: Sequence[str]) -> bool:
    """Plans that promise coverage but not one visit per sub-cell (see planner.balanced.plan)."""
    return any(note.startswith((FALLBACK, WALK_OUT)) for note in plan_notes)


def grid_of(rows: Sequence[str]) -> OccupancyGrid:
    """Coarse-cell picture ('#' blocked) as a sub-cell grid."""
    coarse = np.array([[ch != "#" for ch in row] for row in rows], dtype=bool)
    return OccupancyGrid(expand(coarse))


@st.composite
def instances(draw: st.DrawFn, max_side: int = 7, max_k: int = 8
              ) -> tuple[OccupancyGrid, tuple[SubCell, ...], int]:
    """A random coarse map, k random distinct starts in its largest component, a seed."""
    h = draw(st.integers(1, max_side))
    w = draw(st.integers(1, max_side))
    seed = draw(st.integers(0, 10_000))
    rng = np.random.default_rng(seed)
    density = draw(st.sampled_from([0.0, 0.1, 0.25, 0.4]))
    coarse = rng.random((h, w)) >= density
    if not coarse.any():
        coarse[0, 0] = True
    grid = OccupancyGrid(expand(coarse))
    labels, _ = label_components(coarse)
    biggest = int(np.bincount(labels.ravel())[1:].max())
    k = draw(st.integers(1, min(max_k, 4 * biggest)))
    return grid, random_starts(grid, k, seed), seed


@st.composite
def crowded(draw: st.DrawFn) -> tuple[OccupancyGrid, tuple[SubCell, ...], int]:
    """Small maps where several robots start in the same cell (2 to 4 per cell)."""
    grid, starts, seed = draw(instances(max_side=5, max_k=4))
    area = work_area(grid, starts)
    cells = np.argwhere(area.cells)
    rng = np.random.default_rng(seed)
    extra: list[SubCell] = []
    for _ in range(draw(st.integers(1, 3))):
        r, c = cells[rng.integers(len(cells))]
        subs = list(sub_cells_of((int(r), int(c))))
        count = int(rng.integers(2, 5))
        extra.extend(subs[i] for i in rng.choice(4, size=count, replace=False))
    merged = tuple(dict.fromkeys([*starts, *extra]))
    return grid, merged, seed


def check_regions(parts: Partition, area_cells: np.ndarray, starts: Sequence[SubCell]) -> None:
    """Regions tile the area's sub-cells; whole cells connected; leaves hang off own cells."""
    owner = np.full(expand(area_cells).shape, -1)
    for region in parts.regions:
        assert region.start == starts[region.robot]
        subs = [s for cell in region.cells for s in sub_cells_of(cell)]
        subs += [s for leaf in region.leaves for s in leaf.subs]
        for s in subs:
            assert owner[s] == -1, f"sub-cell {s} in two regions"
            owner[s] = region.robot
        assert region.start in subs
        if region.cells:
            mask = np.zeros(area_cells.shape, dtype=bool)
            mask[tuple(np.array(region.cells).T)] = True
            assert label_components(mask)[1] == 1, f"robot {region.robot}: split region"
        for leaf in region.leaves:
            assert set(leaf.subs) <= set(sub_cells_of(leaf.cell))
            if leaf.anchor is not None:
                assert leaf.anchor in region.cells
                assert abs(leaf.anchor[0] - leaf.cell[0]) + abs(leaf.anchor[1] - leaf.cell[1]) == 1
            else:
                assert not region.cells
    assert ((owner >= 0) == expand(area_cells)).all()


def check_balanced(grid: OccupancyGrid, starts: tuple[SubCell, ...], seed: int) -> None:
    area = work_area(grid, starts)
    plan = balanced_plan(area, seed=seed)
    assert plan.algo == "balanced"
    assert plan.k == len(starts)
    assert plan.makespan >= math.ceil(area.n / len(starts)) - 1
    if relaxed(plan.notes):
        check_plan(plan, area, max_visits=len(starts) + 1, own_revisits_only=False)
        return
    check_plan(plan, area)  # every sub-cell exactly once, by one robot, 4-adjacent moves
    parts = partition(area, seed=seed)
    assert parts is not None
    check_regions(parts, area.cells, starts)
    assert [rp.steps for rp in plan.robots] == [size - 1 for size in parts.sizes]
    assert sum(rp.steps + 1 for rp in plan.robots) == area.n


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
    grid = grid_of(["....."])
    plan = balanced_plan(work_area(grid, ((0, 8), (1, 8))), seed=0)
    assert not relaxed(plan.notes)
    check_plan(plan)
    assert sum(rp.steps + 1 for rp in plan.robots) == 20


def test_robot_boxed_in_a_dead_end_walks_out() -> None:
    # Robot 0 starts in a one-cell dead end whose only exit is robot 1's start cell: no
    # connected region holding robot 0's start can have more than that cell.
    grid = grid_of(["#.#######", ".........", "........."])
    area = work_area(grid, ((1, 2), (2, 2)))
    bound = math.ceil(area.n / 2) - 1
    plan = balanced_plan(area, seed=0)
    assert any(note.startswith(WALK_OUT) for note in plan.notes)
    check_plan(plan, area, max_visits=2, own_revisits_only=False)
    # Two moves out (through robot 1's start cell), then regions balanced with that in mind.
    assert plan.makespan <= bound + 3
    stuck = partition(area, seed=0)
    assert stuck is not None and min(stuck.sizes) == 4  # without walking out: 4 vs 72
    result = simulate_failures(plan, {0: 1})
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


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(max_side=3, max_k=3))
def test_balance_matches_brute_force_on_tiny_maps(
        case: tuple[OccupancyGrid, tuple[SubCell, ...], int]) -> None:
    grid, starts, seed = case
    area = work_area(grid, starts)
    home = {(r // 2, c // 2) for r, c in starts}
    if len(home) < len(starts) or area.cell_count > 8:
        return  # the whole-cell oracle needs one robot per cell and a small search
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
    result = simulate_failures(plan, failures, detection_delay=delay)
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


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(max_side=6, max_k=6))
def test_takeover_without_failures_is_the_plan(
        case: tuple[OccupancyGrid, tuple[SubCell, ...], int]) -> None:
    grid, starts, seed = case
    area = work_area(grid, starts)
    plan = balanced_plan(area, seed=seed)
    result = simulate_failures(plan, {})
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
    result = simulate_failures(plan, {1: 0})
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
        simulate_failures(plan, {5: 1})
    with pytest.raises(UnsupportedPlanError, match=">= 0"):
        simulate_failures(plan, {0: -1})
    with pytest.raises(UnsupportedPlanError, match="negative"):
        simulate_failures(plan, {}, detection_delay=-1)


def test_shared_cell_division_is_always_found() -> None:
    cell = (1, 1)
    subs = sub_cells_of(cell)
    for count in (2, 3, 4):
        for chosen in itertools.combinations(subs, count):
            share = share_cell(cell, list(range(count)), list(chosen), lambda _: False)
            kept = [s for _, keep, _ in share.parts for s in keep]
            assert sorted(kept) == sorted(subs)


# --- squeezed robots moved to roomier seeds (relocate.py) ------------------------------


def _cell_distances(area_cells: np.ndarray, sources: Sequence[tuple[int, int]]
                    ) -> dict[tuple[int, int], int]:
    """Oracle: breadth-first distances over a grid's free cells from the nearest source."""
    h, w = area_cells.shape
    dist = dict.fromkeys(sources, 0)
    frontier = list(sources)
    while frontier:
        nxt = []
        for r, c in frontier:
            for cell in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
                if 0 <= cell[0] < h and 0 <= cell[1] < w and area_cells[cell] \
                        and cell not in dist:
                    dist[cell] = dist[(r, c)] + 1
                    nxt.append(cell)
        frontier = nxt
    return dist


def _is_cut(area_cells: np.ndarray, cell: tuple[int, int]) -> bool:
    without = area_cells.copy()
    without[cell] = False
    return bool(label_components(without)[1] > label_components(area_cells)[1])


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(max_side=7, max_k=8), st.integers(1, 4))
def test_relocation_walks_go_to_roomier_open_cells(
        case: tuple[OccupancyGrid, tuple[SubCell, ...], int], radius: int) -> None:
    grid, starts, seed = case
    area = work_area(grid, starts)
    state = _partition_state(area, seed, None, None)
    if state is None:
        return
    homes = [(r // 2, c // 2) for r, c in starts]
    together = relocation_routes(area, state, range(len(starts)), radius)
    targets = [(w[-1][0] // 2, w[-1][1] // 2) for w in together.values()]
    assert len(set(targets)) == len(targets)
    assert not set(targets) & set(homes)
    for robot in range(len(starts)):  # one at a time: room is measured from the others' homes
        walk = relocation_routes(area, state, [robot], radius).get(robot)
        if walk is None:
            continue
        check_path_moves(walk)
        assert walk[0] == starts[robot]
        assert all(area.sub_cells[s] for s in walk)
        target = (walk[-1][0] // 2, walk[-1][1] // 2)
        reach = _cell_distances(area.sub_cells, [starts[robot]])  # a shortest walk there
        assert len(walk) - 1 == min(reach[s] for s in sub_cells_of(target))
        assert target not in homes and not _is_cut(area.cells, target)
        assert _cell_distances(area.cells, [homes[robot]])[target] <= radius
        others = [h for i, h in enumerate(homes) if i != robot]
        room = _cell_distances(area.cells, others)
        assert room[target] > room[homes[robot]]


def _issue_instance(k: int, seed: int, obstacles: int = 80) -> WorkArea:
    """The issue's setting (as benchmarks/bench_balanced.py): 20 x 30 cells, random blocks."""
    rng = np.random.default_rng(seed)
    coarse = np.ones((20, 30), dtype=bool)
    coarse.ravel()[rng.choice(coarse.size, size=obstacles, replace=False)] = False
    grid = OccupancyGrid(expand(coarse))
    return work_area(grid, random_starts(grid, k, seed))


@pytest.mark.parametrize(("k", "seed"), [(20, 4), (30, 2), (30, 5)])
def test_crowded_starts_plan_is_valid_and_never_worse_than_one_partition(
        k: int, seed: int) -> None:
    # Instances where balancing stalls on strips (see docs/balanced.md): whatever walks the
    # plan adds, it covers everything, and its makespan (walks included) is no larger than
    # that of the single partition without them.
    area = _issue_instance(k, seed)
    plan = balanced_plan(area, seed=seed)
    alone = partition(area, seed=seed)
    assert alone is not None
    if relaxed(plan.notes):
        check_plan(plan, area, max_visits=k + 1, own_revisits_only=False)
    else:
        check_plan(plan, area)
    assert plan.makespan <= max(alone.sizes) - 1
    assert plan.makespan >= math.ceil(area.n / k) - 1
    for rp in plan.robots:  # a walk then its region: all moves 4-adjacent, start kept
        check_path_moves(rp.path)
        assert rp.path[0] == area.starts[rp.robot]
