"""Optimal backtracking MSTC (opt) against brute force, bounds and the simpler algorithms."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from oracles import assert_tiles, brute_force_opt

from planner.allocation import allocate
from planner.errors import InfeasiblePlanError, PlannerError
from planner.types import RobotAllocation

SPEEDS = (0.5, 1.0, 4 / 3, 2.0, 3.0)


@st.composite
def instances(draw: st.DrawFn, max_n: int = 14, max_k: int = 4) -> tuple[int, list[int]]:
    n = draw(st.integers(1, max_n))
    k = draw(st.integers(1, min(max_k, n)))
    positions = draw(st.lists(st.integers(0, n - 1), min_size=k, max_size=k, unique=True))
    return n, positions


def makespan(allocations: tuple[RobotAllocation, ...],
             speeds: list[float] | None = None) -> float:
    return max(a.steps / (1.0 if speeds is None else speeds[a.robot]) for a in allocations)


@settings(max_examples=150, deadline=None)
@given(instances())
def test_opt_equals_brute_force(instance: tuple[int, list[int]]) -> None:
    n, positions = instance
    allocations = allocate("opt", n, positions)
    assert_tiles(n, allocations)
    assert makespan(allocations) == brute_force_opt(n, positions)


@settings(max_examples=150, deadline=None)
@given(instances(), st.data())
def test_opt_equals_brute_force_heterogeneous(instance: tuple[int, list[int]],
                                              data: st.DataObject) -> None:
    n, positions = instance
    k = len(positions)
    speeds = data.draw(st.lists(st.sampled_from(SPEEDS), min_size=k, max_size=k))
    fuel = data.draw(st.lists(st.none() | st.integers(0, n + 2), min_size=k, max_size=k))
    best = brute_force_opt(n, positions, speeds, fuel)
    if math.isinf(best):
        with pytest.raises(InfeasiblePlanError, match="fuel"):
            allocate("opt", n, positions, speeds=speeds, fuel=fuel)
        return
    allocations = allocate("opt", n, positions, speeds=speeds, fuel=fuel)
    assert_tiles(n, allocations)
    assert makespan(allocations, speeds) == pytest.approx(best, rel=1e-12)
    for a in allocations:
        limit = fuel[a.robot]
        assert limit is None or a.steps <= limit


@settings(max_examples=60, deadline=None)
@given(instances(max_n=400, max_k=25))
def test_opt_bounds_and_order(instance: tuple[int, list[int]]) -> None:
    n, positions = instance
    k = len(positions)
    opt = makespan(allocate("opt", n, positions))
    bt = makespan(allocate("bt", n, positions))
    nb = makespan(allocate("nb", n, positions))
    assert math.ceil(n / k) - 1 <= opt <= bt <= nb


@settings(max_examples=40, deadline=None)
@given(instances(max_n=300, max_k=12), st.data())
def test_opt_heterogeneous_large_is_valid_and_beats_bt(instance: tuple[int, list[int]],
                                                      data: st.DataObject) -> None:
    n, positions = instance
    k = len(positions)
    speeds = data.draw(st.lists(st.sampled_from(SPEEDS), min_size=k, max_size=k))
    allocations = allocate("opt", n, positions, speeds=speeds)
    assert_tiles(n, allocations)
    # bt ignores speeds, but its allocation is still a candidate that opt must match or beat
    assert makespan(allocations, speeds) <= makespan(allocate("bt", n, positions), speeds)


@settings(max_examples=40, deadline=None)
@given(instances(max_n=600, max_k=30))
def test_opt_fuel_and_time_searches_agree(instance: tuple[int, list[int]]) -> None:
    # beyond brute-force sizes: capping every tank at opt - 1 moves is the same constraint as
    # a makespan of opt - 1, so the fuel path must find it infeasible and opt feasible
    n, positions = instance
    best = int(makespan(allocate("opt", n, positions)))
    if best == 0:
        return
    with pytest.raises(InfeasiblePlanError):
        allocate("opt", n, positions, fuel=[best - 1] * len(positions))
    assert makespan(allocate("opt", n, positions, fuel=[best] * len(positions))) == best


def test_single_robot_walks_the_cycle_once() -> None:
    (only,) = allocate("opt", 17, [5])
    assert only.steps == 16
    assert_tiles(17, (only,))


def test_every_sub_cell_a_robot_costs_nothing() -> None:
    allocations = allocate("opt", 5, [4, 2, 0, 1, 3])
    assert all(a.steps == 0 and a.legs == () for a in allocations)


def test_fuel_total_shortfall_is_named() -> None:
    with pytest.raises(InfeasiblePlanError, match=r"total fuel is 4 moves but 18 sub-cells"):
        allocate("opt", 20, [0, 10], fuel=[2, 2])


def test_fuel_gap_shortfall_names_the_robots() -> None:
    with pytest.raises(InfeasiblePlanError, match=r"robots 1 and 2 have 1 \+ 1 moves"):
        allocate("opt", 30, [0, 1, 20], fuel=[None, 1, 1])


@pytest.mark.parametrize(("n", "starts", "fuel"), [
    (20, [0, 10], [18, 0]),  # the total is exactly the 18 sub-cells: short only by turning back
    (30, [0, 5, 24], [10, 9, 9]),  # robots 1 and 2 have exactly the 18 between them
])
def test_fuel_exactly_at_a_named_limit_blames_the_turning_back(
        n: int, starts: list[int], fuel: list[int]) -> None:
    # At the boundary neither the total nor the pair is short; brute force agrees that the
    # limits still make coverage impossible, and the message says why.
    assert brute_force_opt(n, starts, fuel=fuel) == math.inf
    with pytest.raises(InfeasiblePlanError, match="walking both ways costs extra moves"):
        allocate("opt", n, starts, fuel=fuel)


def test_fuel_exactly_enough_is_feasible() -> None:
    (only,) = allocate("opt", 10, [0], fuel=[9])
    assert only.steps == 9
    with pytest.raises(InfeasiblePlanError) as caught:
        allocate("opt", 10, [0], fuel=[8])
    assert "\n" not in str(caught.value)
    assert isinstance(caught.value, PlannerError)


def test_fuel_forces_a_slower_allocation() -> None:
    # unlimited, two robots side by side split the cycle evenly; a short tank on robot 0 makes
    # robot 1 do more, and the makespan must still be the brute-force optimum
    free = makespan(allocate("opt", 12, [0, 1]))
    limited = allocate("opt", 12, [0, 1], fuel=[2, None])
    assert limited[0].steps <= 2
    assert makespan(limited) == brute_force_opt(12, [0, 1], fuel=[2, None]) > free
