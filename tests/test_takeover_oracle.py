"""The independent takeover oracle (tests/takeover_oracle.py): hand-derived cases, exhaustive
small cycles against the papers' theorems and a brute-force reading of the target rule, and
agreement with planner.offline.lockstep.simulate_failures on many seeded nb/bt/opt plans."""

from __future__ import annotations

import itertools
import random
from collections.abc import Iterator, Sequence

import numpy as np
import pytest
from takeover_oracle import OracleRun, run, run_plan, walks_as_subcells

from planner.cycle import stc_cycle
from planner.grid import expand, label_components, work_area
from planner.offline.lockstep import simulate_failures
from planner.offline.machine import OfflineRobot
from planner.offline.plan import make_plan
from planner.trees import TREE_KINDS, build_tree
from planner.types import Cycle, Direction, Leg, OccupancyGrid, Plan, RobotPlan


def strip_cycle(width: int) -> Cycle:
    """The 4 * width cycle around a 1 x width row of cells."""
    return stc_cycle(build_tree(np.ones((1, width), dtype=bool), "dfs"))


def legs_of(n: int, start: int, walk: Sequence[int]) -> tuple[Leg, ...]:
    legs: list[Leg] = []
    at = start
    for nxt in walk:
        direction = Direction.CCW if (nxt - at) % n == 1 else Direction.CW
        assert (at + direction.sign - nxt) % n == 0, "a walk moves to a neighbour"
        if legs and legs[-1].direction is direction:
            legs[-1] = Leg(direction, legs[-1].length + 1)
        else:
            legs.append(Leg(direction, 1))
        at = nxt
    return tuple(legs)


def plan_of(cycle: Cycle, robots: Sequence[tuple[int, Sequence[int]]]) -> Plan:
    """Robot i starts at robots[i][0] and walks the cycle indices robots[i][1]."""
    n = cycle.n
    return Plan("oracle", cycle, tuple(
        RobotPlan(i, cycle.at(start), start, legs_of(n, start, walk),
                  tuple(cycle.at(x) for x in (start, *walk)))
        for i, (start, walk) in enumerate(robots)))


def assert_agrees(plan: Plan, failures: dict[int, int], delay: int = 0) -> OracleRun:
    """The oracle and simulate_failures give the same walks, takeovers and coverage times."""
    mine = run_plan(plan, failures, delay)
    theirs = simulate_failures(plan, failures, detection_delay=delay, recovery="takeover")
    legs = [(rp.start_index, rp.legs) for rp in plan.robots]
    context = f"failures {failures}, delay {delay}, plan {legs}"
    got = walks_as_subcells(plan, mine)
    for robot, walk in zip(theirs.robots, theirs.walks, strict=True):
        assert list(walk) == got[robot], f"robot {robot}: {context}"
    assert [(t.taker, t.dead, t.time) for t in theirs.takeovers] == mine.takeovers, context
    assert theirs.complete == mine.complete, context
    assert theirs.coverage_time == mine.coverage_time, context
    on = plan.cycle.index >= 0
    first = theirs.first_time[on][plan.cycle.index[on].argsort()]
    assert [mine.first_time.get(i, -1) for i in range(plan.cycle.n)] == list(first), context
    return mine


# ---- hand-derived cases on the 12-cycle ------------------------------------------------

NB = [(0, [1, 2, 3]), (4, [5, 6, 7]), (8, [9, 10, 11])]


def test_nb_death_mid_section_is_walked_to_the_end_of_the_region() -> None:
    # robot 1 covered 4, 5; robot 0 ends at 3 at t=3 and walks 4..7, arriving at t=7
    result = run(12, {0: 0, 1: 4, 2: 8}, {0: [1, 2, 3], 1: [5, 6, 7], 2: [9, 10, 11]}, {1: 1})
    assert result.walks == {0: [0, 1, 2, 3, 4, 5, 6, 7], 1: [4, 5], 2: [8, 9, 10, 11]}
    assert result.takeovers == [(0, 1, 3)]
    assert result.coverage_time == 7
    assert_agrees(plan_of(strip_cycle(3), NB), {1: 1})


def test_bt_takeover_stops_at_the_last_uncovered_sub_cell_not_at_the_region_end() -> None:
    # robot 1 (region 4..11) went CCW to 11 first and dies back at 11 after 5 moves: only 4, 5
    # are left, so robot 0 walks 4, 5 (not on to 11)
    robots = [(0, [1, 2, 3]), (6, [7, 8, 9, 10, 11, 10, 9, 8, 7, 6, 5, 4])]
    result = run(12, {0: 0, 1: 6}, {0: robots[0][1], 1: robots[1][1]}, {1: 5})
    assert result.walks[0] == [0, 1, 2, 3, 4, 5]
    assert result.takeovers == [(0, 1, 5)]
    assert result.coverage_time == 7
    assert_agrees(plan_of(strip_cycle(3), robots), {1: 5})


def test_chained_takeovers_by_one_watcher() -> None:
    result = run(12, {0: 0, 1: 4, 2: 8}, {0: [1, 2, 3], 1: [5, 6, 7], 2: [9, 10, 11]},
                 {1: 0, 2: 0})
    assert result.walks[0] == list(range(12))
    assert result.takeovers == [(0, 1, 3), (0, 2, 7)]
    assert result.coverage_time == 11
    assert_agrees(plan_of(strip_cycle(3), NB), {1: 0, 2: 0})


def test_a_death_after_the_region_is_done_costs_nothing() -> None:
    result = run(12, {0: 0, 1: 4, 2: 8}, {0: [1, 2, 3], 1: [5, 6, 7], 2: [9, 10, 11]}, {1: 10})
    assert result.takeovers == []
    assert result.coverage_time == 3
    assert_agrees(plan_of(strip_cycle(3), NB), {1: 10})


def test_detection_delay_makes_the_watcher_wait() -> None:
    # robot 1 dies at 2 (covered 4..6), known at 5: robot 0 waits at 3, walks 4..7 from t=5
    result = run(12, {0: 0, 1: 4, 2: 8}, {0: [1, 2, 3], 1: [5, 6, 7], 2: [9, 10, 11]},
                 {1: 2}, delay=3)
    assert result.walks[0] == [0, 1, 2, 3, 4, 5, 6, 7]
    assert result.takeovers == [(0, 1, 5)]
    assert result.coverage_time == 9
    assert_agrees(plan_of(strip_cycle(3), NB), {1: 2}, 3)


def test_a_lone_survivor_walks_round_to_every_dead_region() -> None:
    result = run(12, {0: 0, 1: 4, 2: 8}, {0: [1, 2, 3], 1: [5, 6, 7], 2: [9, 10, 11]},
                 {0: 0, 1: 0})
    assert result.walks[2] == [8, 9, 10, 11, 0, 1, 2, 3, 4, 5, 6, 7]
    assert result.takeovers == [(2, 0, 3), (2, 1, 7)]
    assert result.coverage_time == 11
    assert_agrees(plan_of(strip_cycle(3), NB), {0: 0, 1: 0})


# ---- exhaustive small cycles -----------------------------------------------------------


def region_plans(n: int, k: int) -> Iterator[list[tuple[int, list[int]]]]:
    """Every plan of k robots on the n-cycle whose regions tile it: each robot covers its
    arc out-and-back in either order (nb when it starts at the arc's first index)."""
    for starts in itertools.combinations(range(n), k):
        choices = []
        for j, s in enumerate(starts):
            previous = starts[j - 1] if k > 1 else s - n + 1
            gap = (s - previous) % n if k > 1 else n - 1
            choices.append([(s - back) % n for back in range(max(gap, 1))])
        for firsts in itertools.product(*choices):
            for ccw_first in itertools.product([True, False], repeat=k):
                robots = []
                for j, s in enumerate(starts):
                    end = (firsts[(j + 1) % k] - 1) % n
                    forward = (end - s) % n
                    backward = (s - firsts[j]) % n
                    ahead = [(s + d) % n for d in range(1, forward + 1)]
                    behind = [(s - d) % n for d in range(1, backward + 1)]
                    if ahead and behind:
                        first, second = (ahead, behind) if ccw_first[j] else (behind, ahead)
                        walk = first + first[-2::-1] + [s] + second
                    else:
                        walk = ahead or behind
                    robots.append((s, walk))
                yield robots


def check_rules(n: int, robots: list[tuple[int, list[int]]], failures: dict[int, int],
                result: OracleRun) -> None:
    """The papers' theorems and a brute-force reading of the takeover target."""
    k = len(robots)
    own_moves = [len(w) for _, w in robots]
    if len(failures) < k:
        assert result.complete, "Theorem 3: complete while one robot survives"
    if not failures:
        assert result.coverage_time == max(own_moves)
        nb = all(len({s, *w}) == len(w) + 1 for s, w in robots)
        assert max(result.visits().values()) <= (1 if nb else 2)
    for r, walk in result.walks.items():
        own = [robots[r][0], *robots[r][1]]
        assert walk[:len(own)] == own[:len(walk)], "own section first"
        if r in failures:
            assert len(walk) - 1 <= failures[r]
    # Brute force: each takeover walk is the shortest CCW walk from the taker's position that
    # covers every sub-cell of the dead robot's region still uncovered at the decision.
    for taker, dead, t in result.takeovers:
        region = {robots[dead][0], *robots[dead][1]}
        open_cells = {i for i in region if result.first_time.get(i, 1 << 30) > t}
        timeline = [(0, robots[taker][0]), *result.arrivals[taker]]
        at = [i for time, i in timeline if time <= t][-1]
        shortest = next(d for d in range(n + 1)
                        if open_cells <= {(at + j) % n for j in range(1, d + 1)})
        walked = [i for time, i in timeline if t < time <= t + shortest]
        if failures.get(taker, 1 << 30) < t + shortest:
            continue  # the taker died on the way
        assert walked == [(at + j) % n for j in range(1, shortest + 1)]


@pytest.mark.parametrize(("width", "k"), [(1, 1), (1, 2), (1, 3), (2, 2), (2, 3)])
def test_exhaustive_small_cycles(width: int, k: int) -> None:
    cycle = strip_cycle(width)
    n = cycle.n
    rng = random.Random(width * 10 + k)
    cases = 0
    every = list(region_plans(n, k))
    # every plan of the smallest cycles; a seeded sample of the larger ones keeps this fast
    for robots in every if len(every) <= 120 else rng.sample(every, 120):
        plan = plan_of(cycle, robots)
        horizon = max(len(w) for _, w in robots) + 1
        schedules: list[dict[int, int]] = [{}]
        for size in range(1, k + 1):
            for dead in itertools.combinations(range(k), size):
                for times in itertools.product(range(horizon + 1), repeat=size):
                    schedules.append(dict(zip(dead, times, strict=True)))
        if len(schedules) > 25:
            schedules = [{}, *rng.sample(schedules[1:], 25)]
        for failures in schedules:
            delay = rng.choice([0, 0, 1, 3])
            result = assert_agrees(plan, failures, delay)
            if delay == 0:
                check_rules(n, robots, failures, result)
            cases += 1
    assert cases > 10


# ---- seeded nb / bt / opt plans --------------------------------------------------------


def seeded_plan(seed: int, algo: str) -> Plan:
    rng = np.random.default_rng(seed)
    free = rng.random((5 + seed % 3, 6)) >= 0.2
    labels, _ = label_components(free)
    cells = labels == int(np.argmax(np.bincount(labels.ravel())[1:])) + 1
    subs = np.argwhere(expand(cells))
    k = int(rng.integers(2, min(6, len(subs) - 1) + 1))
    picks = rng.choice(len(subs), size=k, replace=False)
    starts = [(int(subs[p][0]), int(subs[p][1])) for p in picks]
    area = work_area(OccupancyGrid(expand(cells)), starts)
    tree = build_tree(area.cells, TREE_KINDS[seed % len(TREE_KINDS)], seed=seed)
    return make_plan(area, tree, algo)


def seeded_failures(plan: Plan, rng: random.Random) -> dict[int, int]:
    k = len(plan.robots)
    dead = rng.sample(range(k), rng.randint(1, k))
    return {r: rng.randint(0, plan.makespan) for r in dead}


@pytest.mark.parametrize("algo", ["nb", "bt", "opt"])
def test_oracle_agrees_with_simulate_failures_on_seeded_plans(algo: str) -> None:
    rng = random.Random(algo)
    for seed in range(40):
        plan = seeded_plan(seed, algo)
        assert_agrees(plan, {})
        for _ in range(5):
            assert_agrees(plan, seeded_failures(plan, rng), rng.choice([0, 0, 2]))


def test_the_region_end_mutant_of_the_takeover_target_is_caught(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """Issue 15's surviving mutant: takeover walks to the end of the dead robot's region
    instead of its last uncovered sub-cell. The oracle must disagree with it."""

    def region_end(self: OfflineRobot, robot: int) -> int | None:
        first, size = self.regions[robot]
        offsets = (first + np.arange(size)) % self.cycle.n
        if self.covered[offsets].all():
            return None
        return int(offsets[-1])

    monkeypatch.setattr(OfflineRobot, "last_uncovered", region_end)
    rng = random.Random(15)
    caught = 0
    for seed in range(40):
        for algo in ("bt", "opt"):
            plan = seeded_plan(seed, algo)
            for _ in range(5):
                try:
                    assert_agrees(plan, seeded_failures(plan, rng))
                except AssertionError:
                    caught += 1
    assert caught > 0


def test_check_replayable_refuses_what_the_takeover_semantics_cannot_run() -> None:
    import dataclasses

    from planner.errors import UnsupportedPlanError
    from planner.offline.machine import check_replayable

    plan = plan_of(strip_cycle(3), NB)
    check_replayable(plan)
    fast = dataclasses.replace(plan.robots[1], speed=2.0)
    with pytest.raises(UnsupportedPlanError, match="speed"):
        check_replayable(dataclasses.replace(plan, robots=(plan.robots[0], fast, plan.robots[2])))
    with pytest.raises(UnsupportedPlanError, match="tile"):
        check_replayable(plan_of(strip_cycle(3), NB[:2]))
