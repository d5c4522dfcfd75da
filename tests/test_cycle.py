"""STC cycles over every tree kind, robot ordering, and the shared invariant checkers."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.cycle import order_robots, stc_cycle
from planner.geometry import sub_cells_of
from planner.grid import label_components, work_area
from planner.invariants import (
    InvariantViolation,
    check_coverage,
    check_cycle,
    check_path_moves,
    check_plan,
    check_tree,
)
from planner.trees import TREE_KINDS, build_tree
from planner.types import (
    Cycle,
    Direction,
    Leg,
    OccupancyGrid,
    Plan,
    RobotPlan,
    SpanningTree,
    SubCell,
)


@st.composite
def connected_cells(draw: st.DrawFn, max_side: int = 12) -> np.ndarray:
    """A random obstacle grid reduced to its largest 4-connected component."""
    h = draw(st.integers(1, max_side))
    w = draw(st.integers(1, max_side))
    density = draw(st.sampled_from([0.0, 0.15, 0.3, 0.45]))
    seed = draw(st.integers(0, 2**32 - 1))
    free = np.random.default_rng(seed).random((h, w)) >= density
    if not free.any():
        free[0, 0] = True
    labels, _ = label_components(free)
    sizes = np.bincount(labels.ravel())[1:]
    return labels == int(np.argmax(sizes)) + 1


def nb_plan(cycle: Cycle, starts: list[SubCell]) -> Plan:
    """Non-backtracking MSTC: each robot walks CCW up to just before the next robot."""
    n = cycle.n
    positions = [cycle.position(s) for s in starts]
    order = order_robots(cycle, starts)
    robots = []
    for robot, s in enumerate(positions):
        nxt = positions[order[(order.index(robot) + 1) % len(order)]]
        forward = (nxt - s - 1) % n if len(starts) > 1 else n - 1
        legs = (Leg(Direction.CCW, forward),) if forward else ()
        path = tuple(cycle.at(s + j) for j in range(forward + 1))
        robots.append(RobotPlan(robot, starts[robot], s, legs, path))
    return Plan("nb-test", cycle, tuple(robots))


@settings(max_examples=80, deadline=None)
@given(cells=connected_cells(), kind=st.sampled_from(TREE_KINDS),
       seed=st.one_of(st.none(), st.integers(0, 10**6)), data=st.data())
def test_cycle_circles_every_tree(cells: np.ndarray, kind: str, seed: int | None,
                                  data: st.DataObject) -> None:
    tree = build_tree(cells, kind, seed=seed)
    check_tree(tree)
    subs = [s for r, c in zip(*np.nonzero(cells), strict=True) for s in sub_cells_of((r, c))]
    start = data.draw(st.sampled_from(subs))
    cycle = stc_cycle(tree, start=start)
    check_cycle(cycle, tree)
    assert cycle.at(0) == start


@settings(max_examples=40, deadline=None)
@given(cells=connected_cells(max_side=8), kind=st.sampled_from(TREE_KINDS), data=st.data())
def test_order_robots_follows_the_cycle(cells: np.ndarray, kind: str,
                                        data: st.DataObject) -> None:
    cycle = stc_cycle(build_tree(cells, kind, seed=1))
    path = [cycle.at(i) for i in range(cycle.n)]
    starts = data.draw(st.lists(st.sampled_from(path), min_size=1, max_size=6, unique=True))
    order = order_robots(cycle, starts)
    assert sorted(order) == list(range(len(starts)))
    # walking the cycle from index 0 meets the robots in exactly that order
    met = [starts.index(s) for s in path if s in starts]
    assert order == met


def test_order_robots_rejects_starts_off_the_cycle() -> None:
    cycle = stc_cycle(build_tree(np.ones((2, 2), dtype=bool), "dfs"))
    with pytest.raises(ValueError, match=r"robots \[1\]"):
        order_robots(cycle, [(0, 0), (9, 9)])


@settings(max_examples=40, deadline=None)
@given(cells=connected_cells(max_side=8), kind=st.sampled_from(TREE_KINDS), data=st.data())
def test_nonbacktracking_plan_passes_check_plan(cells: np.ndarray, kind: str,
                                                data: st.DataObject) -> None:
    tree = build_tree(cells, kind, seed=4)
    cycle = stc_cycle(tree)
    path = [cycle.at(i) for i in range(cycle.n)]
    starts = data.draw(st.lists(st.sampled_from(path), min_size=1, max_size=5, unique=True))
    grid = OccupancyGrid(np.repeat(np.repeat(cells, 2, axis=0), 2, axis=1))
    area = work_area(grid, starts)
    plan = nb_plan(cycle, starts)
    check_plan(plan, area)
    check_plan(plan)


# --- the checkers must be able to fail -------------------------------------------------

def square_tree() -> SpanningTree:
    return build_tree(np.ones((2, 2), dtype=bool), "dfs", seed=None)


def test_check_cycle_rejects_a_shortcut_through_the_tree() -> None:
    tree = build_tree(np.ones((1, 2), dtype=bool), "dfs", seed=None)
    good = stc_cycle(tree)
    check_cycle(good, tree)
    # the same 8 sub-cells in an order that jumps between columns: not 4-adjacent
    path = np.array(sorted(tuple(p) for p in good.path.tolist()))
    index = np.full(good.index.shape, -1, dtype=np.int64)
    for i, (r, c) in enumerate(path):
        index[r, c] = i
    with pytest.raises(InvariantViolation, match="not a 4-adjacent move"):
        check_cycle(Cycle(path, index), tree)


def test_check_cycle_rejects_a_walk_that_crosses_a_missing_edge() -> None:
    # two cells with the tree edge between them, versus a "tree" that is fine for the
    # cycle's shape but lacks the edge: crossing between the cells is then forbidden
    cells = np.ones((1, 2), dtype=bool)
    tree = build_tree(cells, "dfs", seed=None)
    cycle = stc_cycle(tree)
    no_edge = SpanningTree(cells=cells, right=np.zeros((1, 2), dtype=bool),
                           down=np.zeros((1, 2), dtype=bool))
    with pytest.raises(InvariantViolation, match="without a tree edge"):
        check_cycle(cycle, no_edge)


def test_check_cycle_rejects_wrong_length_and_bad_index() -> None:
    tree = square_tree()
    cycle = stc_cycle(tree)
    short = Cycle(cycle.path[:-1], cycle.index)
    with pytest.raises(InvariantViolation, match="15 sub-cells"):
        check_cycle(short, tree)
    index = cycle.index.copy()
    a, b = cycle.at(0), cycle.at(1)
    index[a], index[b] = index[b], index[a]
    with pytest.raises(InvariantViolation, match=r"cycle\.index"):
        check_cycle(Cycle(cycle.path, index), tree)


def test_check_path_moves() -> None:
    check_path_moves([(0, 0), (0, 1), (1, 1), (1, 0)])
    check_path_moves([(3, 3)])
    with pytest.raises(InvariantViolation, match=r"step 1: .* not a 4-adjacent"):
        check_path_moves([(0, 0), (0, 1), (1, 2)])
    with pytest.raises(InvariantViolation, match="stays still"):
        check_path_moves([(0, 0), (0, 0)])
    check_path_moves([(0, 0), (0, 0), (1, 0)], allow_wait=True)


def test_check_coverage_names_missing_sub_cells() -> None:
    want = np.zeros((4, 4), dtype=bool)
    want[:2, :2] = True
    check_coverage([(0, 0), (0, 1), (1, 0), (1, 1), (3, 3)], want)
    missing = r"1 of 4 sub-cells not covered, e\.g\. \[\(1, 1\)\]"
    with pytest.raises(InvariantViolation, match=missing):
        check_coverage([(0, 0), (0, 1), (1, 0)], want)
    mask = np.zeros((4, 4), dtype=bool)
    mask[:2, :1] = True
    with pytest.raises(InvariantViolation, match="2 of 4"):
        check_coverage(mask, want)


def test_check_plan_rejects_shared_revisits_overlaps_and_gaps() -> None:
    cycle = stc_cycle(square_tree())
    starts = [cycle.at(0), cycle.at(8)]
    plan = nb_plan(cycle, starts)
    check_plan(plan)
    r0, r1 = plan.robots
    # robot 1 walks one step further, onto robot 0's start: a revisit by another robot
    longer = RobotPlan(1, r1.start, r1.start_index, (Leg(Direction.CCW, 8),),
                       (*r1.path, cycle.at(0)))
    overlapping = Plan("t", cycle, (r0, longer))
    with pytest.raises(InvariantViolation, match="more than 1 times"):
        check_plan(overlapping)
    with pytest.raises(InvariantViolation, match="several robots"):
        check_plan(overlapping, max_visits=2)
    # robot 0 stops one short: a gap
    shorter = RobotPlan(0, r0.start, r0.start_index, (Leg(Direction.CCW, 6),), r0.path[:-1])
    with pytest.raises(InvariantViolation, match="not covered"):
        check_plan(Plan("t", cycle, (shorter, r1)))
    # a path that does not begin at the robot's start
    moved = RobotPlan(0, cycle.at(1), 0, r0.legs, r0.path)
    with pytest.raises(InvariantViolation, match="not at its start"):
        check_plan(Plan("t", cycle, (moved, r1)))


def test_check_plan_allows_own_backtracking_when_asked() -> None:
    cycle = stc_cycle(square_tree())
    # one robot: 3 steps CW, back, then all the way CCW
    legs = (Leg(Direction.CW, 3), Leg(Direction.CCW, 3 + 12))
    path = [cycle.at(-j) for j in range(4)]
    path += [cycle.at(-3 + j) for j in range(1, 16)]
    plan = Plan("bt", cycle, (RobotPlan(0, cycle.at(0), 0, legs, tuple(path)),))
    check_plan(plan, max_visits=2)
    with pytest.raises(InvariantViolation, match="more than 1 times"):
        check_plan(plan)
