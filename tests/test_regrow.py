"""The work left after a death partitioned anew from the survivors (planner.balanced.regrow)
and that re-plan's place among planner.offline.rebalance's."""

from __future__ import annotations

import numpy as np
import pytest
from test_rebalance import make, snapshot

from planner.balanced.regrow import _remaining_cells, regrown_work
from planner.cycle import stc_cycle
from planner.grid import work_area
from planner.maps import resolve_world
from planner.offline.rebalance import frozen_at, plan_order, rebalance
from planner.placement import random_starts
from planner.trees import build_tree
from planner.types import Cycle


def strip_cycle(rows: int, cols: int) -> Cycle:
    return stc_cycle(build_tree(np.ones((rows, cols), dtype=bool), "dfs", seed=0),
                     start=(0, 0))


@pytest.mark.parametrize("seed", range(6))
def test_every_uncovered_sub_cell_goes_to_exactly_one_survivor(seed: int) -> None:
    plan, covered, survivors = snapshot(seed)
    found = regrown_work(plan.cycle, covered, [s.position for s in survivors])
    assert found is not None and len(found.work) == len(survivors)
    given = [i for work in found.work for i in work]
    assert len(given) == len(set(given))
    assert set(given) == set(np.flatnonzero(~covered).tolist())
    # a region counts whole cells: at least the work it holds, at most the whole area
    assert all(size >= len(work) for size, work in zip(found.sizes, found.work, strict=True))
    assert sum(found.sizes) <= plan.cycle.n


def test_the_remaining_cells_are_joined_through_the_fewest_covered_cells() -> None:
    """Two uncovered cells at the ends of the top row of a 3 x 7 area, the rest covered:
    the one shortest chain between them is the top row, and nothing else is taken."""
    cycle = strip_cycle(3, 7)
    covered = np.ones(cycle.n, dtype=bool)
    for cell in ((0, 0), (0, 6)):
        covered[cycle.position((2 * cell[0] + 1, 2 * cell[1]))] = False
    cells = _remaining_cells(cycle, covered, [cycle.position((0, 0))])
    assert cells[0].all() and int(cells.sum()) == 7


def test_a_survivor_standing_in_the_covered_part_gets_its_cell_joined() -> None:
    cycle = strip_cycle(3, 7)
    covered = np.ones(cycle.n, dtype=bool)
    covered[cycle.position((0, 0))] = False
    cells = _remaining_cells(cycle, covered, [cycle.position((5, 13))])  # cell (2, 6)
    assert cells[2, 6] and cells[0, 0] and int(cells.sum()) == 9  # a shortest chain: 9 cells


def test_two_survivors_on_one_sub_cell_give_no_partition() -> None:
    plan, covered, survivors = snapshot(0)
    assert regrown_work(plan.cycle, covered, [survivors[0].position] * 2) is None


def test_a_large_fleets_replan_shares_all_the_work_anew() -> None:
    """30 robots of an opt plan on grid30x20, robot 15 dead at 30 % of the makespan: opt's
    sections are unbalanced, and the regrown regions share all the work among the 29
    survivors, so the re-plan ends long before the longest route left (measured: 63
    against 141 moves; 120 with the cuts alone, which reach 12 survivors at most)."""
    grid = resolve_world("grid30x20")
    area = work_area(grid, random_starts(grid, 30, 1))
    plan = make("opt", area, 1)
    step = int(0.3 * plan.makespan)
    covered, survivors = frozen_at(plan, {rp.robot: step for rp in plan.robots}, {15})
    replan = rebalance(plan.cycle, covered, survivors, plan_order(plan))
    assert replan.makespan <= 0.6 * max(len(s.route) for s in survivors)
    assert set(replan.owner) == set(np.flatnonzero(~covered).tolist())
