"""One more robot for the most loaded region (planner/balanced/reinforce.py)."""

from __future__ import annotations

from collections.abc import Sequence

import pytest
from balanced_helpers import grid_distances, instances
from hypothesis import HealthCheck, given, settings

from planner.balanced import balanced_plan
from planner.balanced import regions as regions_module
from planner.balanced.regions import _ideal, _partition_state, plan_regions
from planner.balanced.reinforce import reinforced, score
from planner.balanced.relocate import relocation_routes
from planner.balanced.state import PartitionState, articulation_points
from planner.balanced.types import Partition
from planner.geometry import cell_of
from planner.grid import work_area
from planner.invariants import check_path_moves, check_plan
from planner.maps import resolve_world
from planner.placement import random_starts
from planner.types import OccupancyGrid, SubCell

Routes = dict[int, tuple[SubCell, ...]]


def _largest_load(parts: Partition, routes: Routes) -> int:
    return max(region.size + len(routes.get(region.robot, (region.start,))) - 1
               for region in parts.regions)


@pytest.mark.slow  # two plans at k = 30 on 40 x 40 (5 s); the property test below is quick
def test_a_dead_end_chain_of_rooms_gets_one_more_robot(monkeypatch: pytest.MonkeyPatch
                                                      ) -> None:
    """Rooms 40 x 40, seed 81, k = 30: four robots walk into a chain of four rooms whose
    only way out is the next room and end at 202-203 moves, where the average is 179; the
    transfer chains cannot help (every door is held by one region). A fifth robot can."""
    grid = resolve_world("rooms:40x40:81")
    area = work_area(grid, random_starts(grid, 30, 81))
    plan = balanced_plan(area, seed=81)  # its makespan is the largest load - 1
    monkeypatch.setattr(regions_module, "_reinforced",
                        lambda area, make, goal, state, routes: (state, routes))
    parts_before, routes_before = plan_regions(area, seed=81)
    assert parts_before is not None
    before = _largest_load(parts_before, routes_before)
    average = (area.n + sum(rp.walk_out for rp in plan.robots)) / 30
    assert before - average > 20, "the stall this is about"
    assert plan.makespan + 1 <= before - 15, (before, plan.makespan)
    check_plan(plan, area, max_visits=31, own_revisits_only=False)
    for rp in plan.robots:
        check_path_moves(rp.path)
        assert rp.path[0] == area.starts[rp.robot]


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(instances(max_side=8, max_k=8))
def test_reinforcing_never_raises_the_largest_load_and_walks_are_shortest(
        case: tuple[OccupancyGrid, tuple[SubCell, ...], int]) -> None:
    grid, starts, seed = case
    area = work_area(grid, starts)
    first = _partition_state(area, seed, None, None)
    if first is None:
        return
    # start from relocated robots too, so that some already walk
    routes = relocation_routes(area, first, range(len(starts)), 3)
    seeds = [routes[r][-1] if r in routes else s for r, s in enumerate(starts)]
    state = _partition_state(area, seed, seeds,
                             [len(routes[r]) - 1 if r in routes else 0 for r in range(len(starts))])
    if state is None:
        return
    goal = _ideal(sum(state.load), state.k)

    def make(starts_: Sequence[SubCell], offsets: Sequence[int] | None
             ) -> PartitionState | None:
        return _partition_state(area, seed, starts_, offsets)

    best, walks = reinforced(area, state, routes, goal, make)
    moved = {r for r in walks if walks[r] != routes.get(r)}
    if best is state:  # nothing gained: no walk taken
        assert walks == routes
    else:  # a lower largest load, or as low and held by fewer regions
        assert score(best) < score(state) and moved
    cells = {u for u, free in enumerate(state.free) if free}
    forbidden = articulation_points(cells, state.neighbours) | \
        {state.flat(cell_of(s)) for s in starts}
    for robot in moved:  # a new seed: a shortest walk into a cell no start or door holds
        walk = walks[robot]
        assert walk[0] == starts[robot] and best.starts[robot] == walk[-1]
        check_path_moves(list(walk))
        target = cell_of(walk[-1])
        assert state.flat(target) not in forbidden
        goal_subs = {(2 * target[0] + dr, 2 * target[1] + dc) for dr in (0, 1) for dc in (0, 1)}
        reach = grid_distances(area.sub_cells, [starts[robot]])
        assert len(walk) - 1 == min(reach[sub] for sub in goal_subs)
    for robot in range(len(starts)):  # loads count the walks
        size = 4 * len(best.whole[robot]) + sum(len(x.subs) for x in best.leaves[robot])
        assert best.load[robot] == size + len(walks.get(robot, (starts[robot],))) - 1


def test_a_balanced_map_is_left_alone() -> None:
    grid = resolve_world("obstacles:20x20:0:1")
    area = work_area(grid, random_starts(grid, 4, 1))
    state = _partition_state(area, 1, None, None)
    assert state is not None
    goal = _ideal(sum(state.load), 4)
    assert max(state.load) <= goal
    calls: list[Sequence[SubCell]] = []

    def make(starts: Sequence[SubCell], offsets: Sequence[int] | None) -> None:
        calls.append(starts)

    best, walks = reinforced(area, state, {}, goal, make)
    assert best is state and walks == {} and calls == []


@pytest.mark.slow
def test_robots_are_assigned_again_to_the_reinforced_regions(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Rooms 40 x 40, seed 83, k = 20: once robots were sent to the most loaded regions,
    assigning the robots again to the regions that made (the walks in change with them)
    takes the largest load from 291 to 275 sub-cells (moves + 1)."""
    grid = resolve_world("rooms:40x40:83")
    area = work_area(grid, random_starts(grid, 20, 83))
    parts, routes = plan_regions(area, seed=83)
    monkeypatch.setattr(regions_module, "reassigned", lambda *args: None)
    parts_before, routes_before = plan_regions(area, seed=83)
    assert parts is not None and parts_before is not None
    assert _largest_load(parts, routes) <= _largest_load(parts_before, routes_before) - 10
    for robot, walk in routes.items():  # every walk a walk, from the robot's start
        assert walk[0] == area.starts[robot]
        check_path_moves(list(walk))
