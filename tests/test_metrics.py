"""Metrics: lower bound, turns, TMSTC* eq. 8 time model, coverage and redundancy."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from planner.cycle import stc_cycle
from planner.metrics import (
    KOBUKI,
    PRESETS,
    RV400,
    KinematicParams,
    count_turns,
    coverage,
    lower_bound,
    path_time,
    plan_metrics,
    redundancy,
    revisits_per_robot,
    straight_runs,
)
from planner.trees import build_tree
from planner.types import Direction, Leg, Plan, RobotPlan, SubCell

STEPS = [(0, 1), (1, 0), (0, -1), (-1, 0)]


def walk_from(moves: list[int], start: SubCell = (0, 0)) -> list[SubCell]:
    path = [start]
    for m in moves:
        dr, dc = STEPS[m]
        path.append((path[-1][0] + dr, path[-1][1] + dc))
    return path


@given(n=st.integers(1, 500), k=st.integers(1, 40))
def test_lower_bound_is_the_pigeonhole_bound(n: int, k: int) -> None:
    assert lower_bound(n, k) == math.ceil(n / k) - 1
    # tight: splitting n into k near-equal sections gives a largest one of ceil(n / k)
    sizes = [n // k + (1 if i < n % k else 0) for i in range(k)]
    assert max(sizes) - 1 == lower_bound(n, k)


@settings(max_examples=50)
@given(data=st.data(), n=st.integers(2, 200))
def test_no_partition_beats_the_lower_bound(data: st.DataObject, n: int) -> None:
    k = data.draw(st.integers(1, n))
    cuts = sorted(data.draw(st.lists(st.integers(1, n - 1), min_size=k - 1, max_size=k - 1,
                                     unique=True))) if k > 1 else []
    bounds = [0, *cuts, n]
    sizes = [b - a for a, b in itertools.pairwise(bounds)]
    assert max(sizes) - 1 >= lower_bound(n, k)


def test_lower_bound_rejects_nonsense() -> None:
    with pytest.raises(ValueError, match="k > 0"):
        lower_bound(10, 0)


@pytest.mark.parametrize(("path", "turns"), [
    ([(0, 0)], 0),
    ([(0, 0), (0, 1), (0, 2), (0, 3)], 0),
    ([(0, 0), (0, 1), (1, 1)], 1),
    ([(0, 0), (0, 1), (1, 1), (1, 0)], 2),  # a U-turn over two corners
    ([(0, 0), (0, 1), (0, 0)], 2),  # reversal on the spot
    ([(0, 0), (0, 1), (0, 1), (1, 1)], 1),  # a wait keeps the heading
    ([(0, 0), (1, 0), (1, 1), (0, 1), (0, 0), (1, 0)], 4),  # one lap round a cell and on
])
def test_count_turns_on_hand_made_paths(path: list[SubCell], turns: int) -> None:
    assert count_turns(path) == turns


def test_count_turns_rejects_teleports() -> None:
    with pytest.raises(ValueError, match="not a 4-adjacent"):
        count_turns([(0, 0), (2, 0)])


@given(moves=st.lists(st.integers(0, 3), max_size=40))
def test_turns_count_heading_changes(moves: list[int]) -> None:
    path = walk_from(moves)
    expected = 0
    for a, b in itertools.pairwise(moves):
        expected += 0 if a == b else 2 if (a - b) % 4 == 2 else 1
    assert count_turns(path) == expected
    runs = straight_runs(path)
    assert sum(runs) == len(moves)
    assert len(runs) == sum(1 for i, m in enumerate(moves) if i == 0 or moves[i - 1] != m)


def test_straight_run_matches_eq8_by_hand() -> None:
    # Kobuki, 10 moves of 0.5 m: 5 m > v^2 / 2a = 0.2083 m, so t = d / v + v / 2a
    path = walk_from([0] * 10)
    assert path_time(path, KOBUKI) == pytest.approx(5.0 / 0.5 + 0.5 / (2 * 0.6))
    # a run shorter than v^2 / 2a never reaches v_max: t = sqrt(2d / a)
    tiny = KinematicParams("tiny", tool_width=0.1, v_max=0.5, omega=0.8, accel=0.6)
    assert path_time(walk_from([0]), tiny) == pytest.approx(math.sqrt(2 * 0.1 / 0.6))


def test_turning_path_matches_eq8_by_hand() -> None:
    # 2 moves east, 3 south, 1 north: runs of 1.0 m, 1.5 m, 0.5 m and 1 + 2 quarter turns
    path = walk_from([0, 0, 1, 1, 1, 3])

    def run(d: float) -> float:
        return d / 0.5 + 0.5 / 1.2

    quarter = (math.pi / 2) / 0.8
    assert path_time(path, KOBUKI) == pytest.approx(run(1.0) + run(1.5) + run(0.5) + 3 * quarter)


def test_braking_profile_by_hand() -> None:
    p = KinematicParams("b", tool_width=1.0, v_max=1.0, omega=1.0, accel=1.0, decelerate=True)
    assert p.run_time(0.25) == pytest.approx(2 * math.sqrt(0.25))  # triangular
    assert p.run_time(3.0) == pytest.approx(3.0 + 1.0)  # trapezoid: d / v + v / a
    # braking never makes a run faster than eq. 8's accelerate-only profile
    plain = KinematicParams("p", tool_width=1.0, v_max=1.0, omega=1.0, accel=1.0)
    for d in np.linspace(0.01, 5, 50):
        assert p.run_time(float(d)) >= plain.run_time(float(d))


@pytest.mark.parametrize("params", list(PRESETS.values()))
def test_run_time_is_continuous_and_increasing(params: KinematicParams) -> None:
    ds = np.linspace(0.0, 4.0, 801)
    times = [params.run_time(float(d)) for d in ds]
    assert all(b > a for a, b in itertools.pairwise(times))
    switch = params.v_max**2 / (params.accel if params.decelerate else 2 * params.accel)
    eps = 1e-9
    assert params.run_time(switch + eps) - params.run_time(switch - eps) < 1e-6  # no jump
    # long runs cost d / v_max plus a constant
    assert params.run_time(100.0) - params.run_time(99.0) == pytest.approx(1 / params.v_max)


@settings(max_examples=60)
@given(moves=st.lists(st.integers(0, 3), min_size=1, max_size=40),
       extra=st.integers(0, 3))
def test_path_time_is_monotonic(moves: list[int], extra: int) -> None:
    path = walk_from(moves)
    for params in (KOBUKI, RV400):
        longer = path_time(walk_from([*moves, extra]), params)
        assert longer > path_time(path, params)
        # a straight run of the same length is never slower than the turning path
        assert path_time(walk_from([0] * len(moves)), params) <= path_time(path, params) + 1e-9


def test_kinematic_params_validate() -> None:
    with pytest.raises(ValueError, match="omega"):
        KinematicParams("bad", tool_width=0.5, v_max=0.5, omega=0.0, accel=0.6)


def test_coverage_fraction() -> None:
    area = np.zeros((2, 3), dtype=bool)
    area[:, :2] = True
    assert coverage([[(0, 0), (0, 1)], [(1, 1), (1, 2)]], area) == pytest.approx(3 / 4)
    assert coverage([[(9, 9)]], area) == 0.0
    assert coverage([], np.zeros((2, 2), dtype=bool)) == 1.0


def test_redundancy_and_revisits_by_hand() -> None:
    a = [(0, 0), (0, 1), (0, 0)]  # robot 0 returns to its start at t=2
    b = [(1, 1), (0, 1)]  # robot 1 reaches (0, 1) at t=1, the same time as robot 0
    assert redundancy([a, b]) == 2
    assert revisits_per_robot([a, b]) == (1, 1)  # same step: lower id counts as first
    assert redundancy([[(0, 0), (0, 1)]]) == 0


@settings(max_examples=50)
@given(paths=st.lists(st.lists(st.integers(0, 3), max_size=15), min_size=1, max_size=4),
       offsets=st.lists(st.integers(0, 3), min_size=4, max_size=4))
def test_revisits_sum_to_redundancy(paths: list[list[int]], offsets: list[int]) -> None:
    walks = [walk_from(m, (offsets[i], 0)) for i, m in enumerate(paths)]
    assert sum(revisits_per_robot(walks)) == redundancy(walks)
    visits: dict[SubCell, int] = {}
    for w in walks:
        for s in w:
            visits[s] = visits.get(s, 0) + 1
    assert redundancy(walks) == sum(v - 1 for v in visits.values())


def test_plan_metrics_on_a_nonbacktracking_plan() -> None:
    cycle = stc_cycle(build_tree(np.ones((3, 4), dtype=bool), "kruskal", seed=2))
    n = cycle.n
    starts = [0, 10, 30]
    robots = []
    for i, s in enumerate(starts):
        forward = (starts[(i + 1) % 3] - s - 1) % n
        path = tuple(cycle.at(s + j) for j in range(forward + 1))
        robots.append(RobotPlan(i, cycle.at(s), s, (Leg(Direction.CCW, forward),), path))
    plan = Plan("nb", cycle, tuple(robots))
    m = plan_metrics(plan)
    assert (m.n, m.k) == (n, 3)
    assert m.steps == (9, 19, n - 31)
    assert sum(m.steps) == n - 3  # non-backtracking: every sub-cell but the starts is a move
    assert m.makespan == max(m.steps) >= m.lower_bound == lower_bound(n, 3)
    assert m.redundancy == 0
    assert m.turns == tuple(count_turns(rp.path) for rp in robots)
    assert m.times == tuple(path_time(rp.path, KOBUKI) for rp in robots)
    assert m.makespan_time == max(m.times)
    assert m.ratio == m.makespan / m.lower_bound
