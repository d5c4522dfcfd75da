"""Balanced plans on sparse generated maps: rooms behind doors, 30 % obstacles, mazes.

There regions grown round the starts stall even when the starts are spread, so the spread
seeds of the assignment step (assign.SPACING) are the starts again; the assignment then also
tries farthest-point seeds alone (assign.FAR). Checked against the step it extends, and the
plans on fresh maps of every sparse family for validity.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import pytest
from balanced_helpers import relaxed

from planner.balanced import assign
from planner.balanced.assign import SPACING, assigned_partition, spread_seeds
from planner.balanced.plan import balanced_plan
from planner.balanced.regions import _partition_state
from planner.balanced.state import PartitionState
from planner.geometry import cell_of
from planner.grid import WorkArea, work_area
from planner.invariants import check_path_moves, check_plan
from planner.maps import resolve_world
from planner.placement import random_starts
from planner.types import SubCell


def _instance(spec: str, k: int, seed: int) -> WorkArea:
    grid = resolve_world(spec)
    return work_area(grid, random_starts(grid, k, seed))


def _assigned(area: WorkArea, seed: int, goal: int) -> PartitionState | None:
    found = assigned_partition(
        area, lambda starts, offsets: _partition_state(area, seed, starts, offsets), goal)
    return None if found is None else found[0]


@pytest.mark.slow  # 3-4 s of CPU alone (the quick loop stays near a minute)
def test_farthest_point_seeds_unstall_rooms_whose_starts_are_spread(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # 20 robots on a 40 x 40-cell floor plan: every start is at least SPACING cells from
    # the others, so the spread seeds are the starts and give the stalled regions again;
    # farthest-point seeds, with the robots walking to their regions, must beat them.
    area = _instance("rooms:40x40:1", 20, 1)
    base = PartitionState(area.cells, area.starts)
    starts = [base.flat(cell_of(s)) for s in area.starts]
    assert spread_seeds(base, starts, SPACING) == starts
    grown = _partition_state(area, 1, None, None)
    assert grown is not None
    goal = math.ceil(area.n / 20)
    monkeypatch.setattr(assign, "SPACINGS", (SPACING,))
    spread_only = _assigned(area, 1, goal)
    assert spread_only is None or max(spread_only.load) >= max(grown.load)
    monkeypatch.undo()
    farthest = _assigned(area, 1, goal)
    assert farthest is not None
    assert max(farthest.load) < max(grown.load)
    plan = balanced_plan(area, seed=1)
    assert plan.makespan <= max(farthest.load) - 1


def test_farthest_point_seeds_are_skipped_when_spread_seeds_split_evenly(
        monkeypatch: pytest.MonkeyPatch) -> None:
    # Regions from the spread seeds at the average: only the robots' walks are left, which
    # seeds farther from the starts would lengthen, so no partition is made from them.
    area = _instance("city:24x24:3", 12, 3)
    seeds_made: list[int] = []

    def make(starts: Sequence[SubCell], offsets: Sequence[int] | None) -> PartitionState | None:
        seeds_made.append(offsets is None)
        return _partition_state(area, 3, starts, offsets)

    base = PartitionState(area.cells, area.starts)
    seeds = spread_seeds(base, [base.flat(cell_of(s)) for s in area.starts], SPACING)
    first = _partition_state(area, 3, [(2 * (u // base.width), 2 * (u % base.width))
                                       for u in seeds], None)
    assert first is not None
    even = max(first.load)
    assigned_partition(area, make, even)  # a goal the spread seeds' regions reach
    assert seeds_made.count(True) == 1
    seeds_made.clear()
    assigned_partition(area, make, even - 2)  # one they miss: farthest-point seeds too
    assert seeds_made.count(True) == 2


@pytest.mark.parametrize("spec", ["rooms:24x28:{seed}", "obstacles:24x28:30%:{seed}",
                                  "maze:23x27:{seed}"])
@pytest.mark.parametrize(("k", "seed"), [(6, 11), (12, 12), (20, 13)])
def test_plans_on_sparse_families_cover_and_walk_out_correctly(spec: str, k: int,
                                                               seed: int) -> None:
    area = _instance(spec.format(seed=seed), k, seed)
    plan = balanced_plan(area, seed=seed)
    if relaxed(plan.notes):
        check_plan(plan, area, max_visits=k + 1, own_revisits_only=False)
    else:
        check_plan(plan, area)
    assert plan.makespan >= math.ceil(area.n / k) - 1
    grown = _partition_state(area, seed, None, None)
    if grown is not None:  # never worse than the regions grown round the starts
        assert plan.makespan <= max(grown.load) - 1
    for rp in plan.robots:
        check_path_moves(rp.path)
        assert rp.path[0] == area.starts[rp.robot]
