"""Takeover semantics (paper 003, Alg. 2 / Alg. 4): replay, robustness, hand-derived timings."""

from __future__ import annotations

import importlib.util
from collections.abc import Sequence

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from planner.cycle import order_robots, stc_cycle
from planner.errors import UnsupportedPlanError
from planner.grid import expand, label_components, work_area
from planner.invariants import check_coverage, check_path_moves, check_plan
from planner.offline.lockstep import Takeover, simulate_failures
from planner.offline.machine import region_of
from planner.trees import TREE_KINDS, build_tree
from planner.types import (
    Cycle,
    Direction,
    Leg,
    OccupancyGrid,
    Plan,
    RobotAllocation,
    RobotPlan,
)

HAVE_ALLOCATION = importlib.util.find_spec("planner.allocation") is not None


def walk(cycle: Cycle, start: int, legs: Sequence[Leg]) -> tuple[tuple[int, int], ...]:
    out = [cycle.at(start)]
    at = start
    for leg in legs:
        for _ in range(leg.length):
            at += leg.direction.sign
            out.append(cycle.at(at))
    return tuple(out)


def plan_from_regions(cycle: Cycle, starts: Sequence[int], firsts: Sequence[int],
                      ccw_first: Sequence[bool]) -> Plan:
    """Robot i starts at cycle index starts[i] and covers [firsts[i], next first) in two legs.

    Starts must be increasing and firsts[i] <= starts[i] < firsts[i + 1] (cyclically).
    """
    n = cycle.n
    k = len(starts)
    robots = []
    for i, s in enumerate(starts):
        legs: tuple[Leg, ...]
        end = (firsts[(i + 1) % k] - 1) % n if k > 1 else (firsts[0] - 1) % n
        forward = (end - s) % n
        backward = (s - firsts[i]) % n
        if forward and backward:
            legs = ((Leg(Direction.CCW, forward), Leg(Direction.CW, forward + backward))
                    if ccw_first[i] else
                    (Leg(Direction.CW, backward), Leg(Direction.CCW, backward + forward)))
        elif forward:
            legs = (Leg(Direction.CCW, forward),)
        elif backward:
            legs = (Leg(Direction.CW, backward),)
        else:
            legs = ()
        robots.append(RobotPlan(i, cycle.at(s), s, legs, walk(cycle, s, legs)))
    return Plan("test", cycle, tuple(robots))


def nb_plan(cycle: Cycle, starts: Sequence[int]) -> Plan:
    return plan_from_regions(cycle, starts, starts, [True] * len(starts))


@st.composite
def cycles(draw: st.DrawFn, max_side: int = 7) -> Cycle:
    h = draw(st.integers(1, max_side))
    w = draw(st.integers(1, max_side))
    seed = draw(st.integers(0, 2**32 - 1))
    free = np.random.default_rng(seed).random((h, w)) >= draw(st.sampled_from([0.0, 0.2, 0.35]))
    if not free.any():
        free[0, 0] = True
    labels, _ = label_components(free)
    cells = labels == int(np.argmax(np.bincount(labels.ravel())[1:])) + 1
    return stc_cycle(build_tree(cells, draw(st.sampled_from(TREE_KINDS)), seed=seed))


@st.composite
def plans(draw: st.DrawFn, backtracking: bool = True) -> Plan:
    cycle = draw(cycles())
    n = cycle.n
    k = draw(st.integers(1, min(6, n - 1)))
    starts = sorted(draw(st.lists(st.integers(0, n - 1), min_size=k, max_size=k, unique=True)))
    if not backtracking:
        return nb_plan(cycle, starts)
    # each region begins somewhere in (previous start, own start]
    firsts = []
    for i, s in enumerate(starts):
        previous = starts[i - 1] if k > 1 else s - n + 1
        gap = (s - previous) % n if k > 1 else n - 1
        firsts.append((s - draw(st.integers(0, gap - 1))) % n if gap > 0 else s)
    ccw_first = draw(st.lists(st.booleans(), min_size=k, max_size=k))
    return plan_from_regions(cycle, starts, firsts, ccw_first)


def assert_consistent(plan: Plan, failures: dict[int, int], delay: int = 0) -> None:
    """Invariants of any replay, failures or not."""
    result = simulate_failures(plan, failures, detection_delay=delay, recovery="takeover")
    for rp, executed, moves in zip(plan.robots, result.walks, result.moves, strict=True):
        check_path_moves(executed)
        assert executed[0] == rp.start
        own = min(len(executed), len(rp.path))
        assert executed[:own] == rp.path[:own]  # a robot walks its own plan first
        if rp.robot in failures:
            assert moves <= failures[rp.robot]
    visits = np.zeros(plan.cycle.index.shape, dtype=np.int64)
    for executed in result.walks:
        for s in executed:
            visits[s] += 1
    assert np.array_equal(visits, result.visits)
    if result.complete:
        check_coverage([s for w in result.walks for s in w], plan.cycle.index >= 0)
        assert result.coverage_time == int(result.first_time.max())
    else:
        assert result.coverage_time is None
        assert (result.visits[plan.cycle.index >= 0] == 0).any()


@settings(max_examples=60, deadline=None)
@given(plan=plans())
def test_no_failures_replays_the_plan(plan: Plan) -> None:
    result = simulate_failures(plan, {}, recovery="takeover")
    assert result.complete
    assert result.walks == tuple(rp.path for rp in plan.robots)
    assert result.makespan == plan.makespan
    assert result.coverage_time is not None and result.coverage_time <= plan.makespan
    assert result.takeovers == ()
    on = plan.cycle.index >= 0
    assert result.visits[on].max() <= 2  # Alg. 4: nothing covered more than twice
    assert_consistent(plan, {})


@settings(max_examples=40, deadline=None)
@given(plan=plans(backtracking=False))
def test_no_failures_nonbacktracking_covers_each_sub_cell_once(plan: Plan) -> None:
    result = simulate_failures(plan, {}, recovery="takeover")
    on = plan.cycle.index >= 0
    assert (result.visits[on] == 1).all()
    assert result.coverage_time == plan.makespan


@settings(max_examples=80, deadline=None)
@given(plan=plans(), data=st.data(), delay=st.integers(0, 5))
def test_up_to_k_minus_one_failures_still_complete(plan: Plan, data: st.DataObject,
                                                    delay: int) -> None:
    k = plan.k
    assume(k >= 2)
    dead = data.draw(st.lists(st.integers(0, k - 1), min_size=1, max_size=k - 1, unique=True))
    failures = {r: data.draw(st.integers(0, plan.makespan + 2)) for r in dead}
    result = simulate_failures(plan, failures, detection_delay=delay, recovery="takeover")
    assert result.complete
    assert {t.dead for t in result.takeovers} <= set(dead)
    assert all(t.taker not in failures or t.time < failures[t.taker]
               for t in result.takeovers)
    assert_consistent(plan, failures, delay)


@settings(max_examples=40, deadline=None)
@given(plan=plans(), data=st.data())
def test_all_robots_failing_before_their_end_is_incomplete(plan: Plan,
                                                           data: st.DataObject) -> None:
    assume(any(rp.steps > 0 for rp in plan.robots))
    failures = {rp.robot: data.draw(st.integers(0, max(rp.steps - 1, 0))) for rp in plan.robots}
    result = simulate_failures(plan, failures, recovery="takeover")
    assert not result.complete
    assert result.takeovers == ()
    assert_consistent(plan, failures)


@settings(max_examples=60, deadline=None)
@given(plan=plans(backtracking=False), data=st.data(), delay=st.integers(0, 4))
def test_single_failure_matches_the_hand_derived_timing(plan: Plan, data: st.DataObject,
                                                        delay: int) -> None:
    """One robot j fails at f; its predecessor i (Alg. 2) finishes, waits, then walks j's region.

    If j had not finished (f < s_j), i starts at max(s_i, f + delay) and needs size_j moves
    to reach the end of j's region; everyone else walks their own section.
    """
    k = plan.k
    assume(k >= 2)
    j = data.draw(st.integers(0, k - 1))
    f = data.draw(st.integers(0, plan.makespan + 1))
    order = order_robots(plan.cycle, [rp.start for rp in plan.robots])
    i = order[(order.index(j) - 1) % k]
    steps = [rp.steps for rp in plan.robots]
    result = simulate_failures(plan, {j: f}, detection_delay=delay, recovery="takeover")
    assert result.complete
    if f >= steps[j]:
        assert result.walks == tuple(rp.path for rp in plan.robots)
        assert result.coverage_time == max(steps)
    else:
        size_j = steps[j] + 1
        begin = max(steps[i], f + delay)
        others = max(steps[r] for r in range(k) if r != j)
        assert result.moves[i] == steps[i] + size_j
        assert result.moves[j] == f
        assert result.coverage_time == max(others, begin + size_j)
        assert result.takeovers == (Takeover(i, j, begin),)


def test_chain_takeover_of_two_dead_neighbours() -> None:
    cycle = stc_cycle(build_tree(np.ones((2, 3), dtype=bool), "kruskal", seed=0))
    assert cycle.n == 24
    plan = nb_plan(cycle, [0, 6, 10, 18])  # sections of 6, 4, 8 and 6 sub-cells
    result = simulate_failures(plan, {1: 0, 2: 0}, recovery="takeover")
    assert result.complete
    # robot 0 walks its 5 moves, then robot 1's section (4) and robot 2's section (8)
    assert result.moves == (5 + 4 + 8, 0, 0, 5)
    assert result.takeovers == (Takeover(0, 1, 5), Takeover(0, 2, 9))
    assert result.coverage_time == 17
    on = cycle.index >= 0
    assert sorted(set(result.first_robot[on].tolist())) == [0, 1, 2, 3]
    # robots 1 and 2 covered only their starts; robot 0 covered their sections' remainder
    assert int((result.first_robot == 1).sum()) == 1
    assert int((result.first_robot == 2).sum()) == 1
    assert int((result.visits[on] == 2).sum()) == 2  # the two dead robots' starts


def test_watcher_at_the_cw_end_rewalks_its_own_region() -> None:
    cycle = stc_cycle(build_tree(np.ones((2, 2), dtype=bool), "dfs", seed=None))
    assert cycle.n == 16
    # robot 0 starts at 3, covers [0, 7]: 4 moves CCW to 7, 7 moves CW back to 0
    r0_legs = (Leg(Direction.CCW, 4), Leg(Direction.CW, 7))
    r0 = RobotPlan(0, cycle.at(3), 3, r0_legs, walk(cycle, 3, r0_legs))
    r1_legs = (Leg(Direction.CCW, 7),)
    r1 = RobotPlan(1, cycle.at(8), 8, r1_legs, walk(cycle, 8, r1_legs))
    plan = Plan("bt", cycle, (r0, r1))
    result = simulate_failures(plan, {1: 0}, recovery="takeover")
    assert result.complete
    assert result.moves == (11 + 15, 0)  # 0 -> 15 along the cycle after its own 11 moves
    assert result.coverage_time == 26
    visits = [int(result.visits[cycle.at(i)]) for i in range(16)]
    assert visits == [1, 2, 2, 3, 3, 3, 3, 2, 2, 1, 1, 1, 1, 1, 1, 1]


def test_failure_after_finishing_needs_no_takeover_moves() -> None:
    cycle = stc_cycle(build_tree(np.ones((2, 2), dtype=bool), "dfs", seed=None))
    plan = nb_plan(cycle, [0, 4, 8])  # sections of 4, 4 and 8
    # robot 1 finishes at 3, then dies
    result = simulate_failures(plan, {1: 3}, recovery="takeover")
    assert result.walks == tuple(rp.path for rp in plan.robots)
    # robot 0 finished at 3 and learns of the death at 3 while 8..15 is still open: it takes
    # over the (complete) role, moves nowhere and goes on watching robot 2
    assert result.takeovers == (Takeover(0, 1, 3),)


def test_everyone_but_one_dead_at_start() -> None:
    cycle = stc_cycle(build_tree(np.ones((3, 3), dtype=bool), "random", seed=7))
    n = cycle.n
    plan = nb_plan(cycle, [0, 5, 17, 30])
    result = simulate_failures(plan, {0: 0, 1: 0, 3: 0}, recovery="takeover")
    assert result.complete
    # robot 2 walks its own section, then on round the whole cycle to just before its start
    assert result.moves[2] == n - 1
    assert result.coverage_time == n - 1
    assert [t.dead for t in result.takeovers] == [3, 0, 1]


def test_all_dead_at_start_is_incomplete() -> None:
    cycle = stc_cycle(build_tree(np.ones((2, 2), dtype=bool), "bfs", seed=1))
    plan = nb_plan(cycle, [0, 9])
    result = simulate_failures(plan, {0: 0, 1: 0}, recovery="takeover")
    assert not result.complete
    assert result.coverage_time is None
    assert int(result.covered.sum()) == 2


def test_rejections() -> None:
    cycle = stc_cycle(build_tree(np.ones((2, 2), dtype=bool), "dfs", seed=None))
    plan = nb_plan(cycle, [0, 8])
    with pytest.raises(UnsupportedPlanError, match="robot 5"):
        simulate_failures(plan, {5: 1}, recovery="takeover")
    with pytest.raises(UnsupportedPlanError, match="fails at time -1"):
        simulate_failures(plan, {0: -1}, recovery="takeover")
    fast = RobotPlan(0, plan.robots[0].start, 0, plan.robots[0].legs, plan.robots[0].path,
                     speed=2.0)
    with pytest.raises(UnsupportedPlanError, match=r"speed 2\.0"):
        simulate_failures(Plan("x", cycle, (fast, plan.robots[1])), {}, recovery="takeover")
    short = RobotPlan(0, plan.robots[0].start, 0, (Leg(Direction.CCW, 6),),
                      plan.robots[0].path[:7])
    with pytest.raises(UnsupportedPlanError, match="do not tile"):
        simulate_failures(Plan("x", cycle, (short, plan.robots[1])), {}, recovery="takeover")
    wrong = RobotPlan(0, plan.robots[0].start, 0, plan.robots[0].legs,
                      tuple(reversed(plan.robots[0].path)))
    with pytest.raises(UnsupportedPlanError, match="does not follow its legs"):
        simulate_failures(Plan("x", cycle, (wrong, plan.robots[1])), {}, recovery="takeover")


def test_region_of_reads_both_legs() -> None:
    rp = RobotPlan(0, (0, 0), 5, (Leg(Direction.CW, 2), Leg(Direction.CCW, 6)), ())
    assert region_of(rp, 20) == (3, 7)
    assert region_of(RobotPlan(0, (0, 0), 1, (Leg(Direction.CW, 3),), ()), 20) == (18, 4)


def plan_from_allocations(cycle: Cycle, allocations: Sequence[RobotAllocation]) -> Plan:
    robots = tuple(RobotPlan(a.robot, cycle.at(a.start_index), a.start_index, a.legs,
                             walk(cycle, a.start_index, a.legs)) for a in allocations)
    return Plan("alloc", cycle, robots)


@pytest.mark.skipif(not HAVE_ALLOCATION, reason="planner.allocation is not written yet")
@settings(max_examples=40, deadline=None)
@given(cycle=cycles(), data=st.data())
def test_allocation_plans_survive_failures(cycle: Cycle, data: st.DataObject) -> None:
    from planner.allocation import ALGORITHMS, allocate

    n = cycle.n
    k = data.draw(st.integers(2, min(6, n - 1)))
    positions = data.draw(st.lists(st.integers(0, n - 1), min_size=k, max_size=k, unique=True))
    algo = data.draw(st.sampled_from(ALGORITHMS))
    plan = plan_from_allocations(cycle, allocate(algo, n, positions))
    clean = simulate_failures(plan, {}, recovery="takeover")
    assert clean.complete and clean.makespan == plan.makespan
    dead = data.draw(st.lists(st.integers(0, k - 1), min_size=1, max_size=k - 1, unique=True))
    failures = {r: data.draw(st.integers(0, plan.makespan)) for r in dead}
    assert simulate_failures(plan, failures, recovery="takeover").complete
    assert_consistent(plan, failures)


HAVE_PIPELINE = importlib.util.find_spec("planner.offline.plan") is not None


@pytest.mark.skipif(not HAVE_PIPELINE, reason="planner.offline.plan is not written yet")
@settings(max_examples=25, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), data=st.data())
def test_pipeline_plans_pass_check_plan_and_survive_failures(seed: int,
                                                             data: st.DataObject) -> None:
    from planner.allocation import ALGORITHMS
    from planner.offline.plan import make_plan

    rng = np.random.default_rng(seed)
    free = rng.random((6, 7)) >= 0.2
    labels, _ = label_components(free)
    cells = labels == int(np.argmax(np.bincount(labels.ravel())[1:])) + 1
    subs = np.argwhere(expand(cells))
    k = data.draw(st.integers(1, min(5, len(subs) - 1)))
    picks = rng.choice(len(subs), size=k, replace=False)
    starts = [(int(subs[p][0]), int(subs[p][1])) for p in picks]
    area = work_area(OccupancyGrid(expand(cells)), starts)
    algo = data.draw(st.sampled_from(ALGORITHMS))
    plan = make_plan(area, build_tree(area.cells, data.draw(st.sampled_from(TREE_KINDS)),
                                      seed=seed), algo)
    check_plan(plan, area, max_visits=1 if algo == "nb" else 2)
    clean = simulate_failures(plan, {}, recovery="takeover")
    assert clean.complete and clean.makespan == plan.makespan
    failures = {r: data.draw(st.integers(0, plan.makespan)) for r in range(k - 1)}
    assert simulate_failures(plan, failures, detection_delay=2, recovery="takeover").complete
    assert_consistent(plan, failures, 2)
