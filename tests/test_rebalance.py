"""Re-balancing after deaths (planner.offline.rebalance) as the lockstep oracle runs it:
everything gets covered, every uncovered sub-cell has one live owner whose route reaches it,
the re-plan depends only on its inputs, and it finishes before the papers' takeover."""

from __future__ import annotations

import random
import statistics

import numpy as np
import pytest

from planner.algorithms import algorithm
from planner.geometry import cell_of
from planner.grid import FAR, WorkArea, expand, work_area
from planner.invariants import check_path_moves
from planner.maps import resolve_world
from planner.offline import rebalance as rebalance_module
from planner.offline import shortest
from planner.offline.rebalance import (
    RECOVERIES,
    Replan,
    Survivor,
    frozen_at,
    plan_order,
    rebalance,
)
from planner.offline.shortest import NEAR, Grid
from planner.placement import random_starts
from planner.trees import build_tree
from planner.types import Cycle, OccupancyGrid, Plan

ALGOS = ("nb", "opt", "balanced")


def generated(seed: int, k: int) -> WorkArea:
    rng = np.random.default_rng(seed)
    rows, cols = int(rng.integers(6, 12)), int(rng.integers(6, 14))
    coarse = np.ones((rows, cols), dtype=bool)
    blocked = int(rng.integers(0, rows * cols // 6))
    coarse.ravel()[rng.choice(rows * cols, size=blocked, replace=False)] = False
    grid = OccupancyGrid(expand(coarse), name=f"gen-{seed}")
    return work_area(grid, random_starts(grid, k, seed))


def make(algo: str, area: WorkArea, seed: int) -> Plan:
    tree = build_tree(area.cells, "dfs", seed=seed, starts=[cell_of(s) for s in area.starts])
    plan: Plan = algorithm(algo).load_plan()(area, tree, algo, seed)
    return plan


def random_deaths(plan: Plan, rng: random.Random, count: int) -> dict[int, int]:
    robots = rng.sample([rp.robot for rp in plan.robots], count)
    return {r: rng.randrange(0, max(plan.makespan, 1)) for r in robots}


@pytest.mark.parametrize("algo", ALGOS)
@pytest.mark.parametrize("seed", range(8))
def test_several_deaths_at_random_times_are_all_recovered(algo: str, seed: int) -> None:
    rng = random.Random(seed)
    k = rng.randrange(3, 8)
    area = generated(seed, k)
    plan = make(algo, area, seed)
    deaths = random_deaths(plan, rng, rng.randrange(1, k))
    delay = rng.randrange(0, 4)  # a death known later: the others re-plan without it first
    result = algorithm(algo).load_lockstep()(plan, deaths, detection_delay=delay,
                                             recovery="rebalance")
    assert result.complete and int(result.covered.sum()) == area.n
    assert result.takeovers == ()  # nobody took over in sequence
    for robot, at in deaths.items():
        assert len(result.walks[result.robots.index(robot)]) - 1 <= at


@pytest.mark.slow  # 3-4 s of CPU alone (the quick loop stays near a minute)
def test_two_deaths_in_one_step_and_one_during_the_recovery() -> None:
    grid = resolve_world("office")
    area = work_area(grid, random_starts(grid, 6, 1))
    plan = make("balanced", area, 1)
    replay = algorithm("balanced").load_lockstep()
    for deaths in ({1: 30, 2: 30}, {1: 30, 4: 35}, {0: 10, 1: 20, 2: 30, 3: 40, 4: 50}):
        result = replay(plan, deaths, recovery="rebalance")
        assert result.complete, deaths


def snapshot(seed: int) -> tuple[Plan, np.ndarray, list[Survivor]]:
    """The balanced plan of a generated area at one robot's death, half-way through."""
    area = generated(seed, 5)
    plan = make("balanced", area, seed)
    covered, survivors = frozen_at(plan, {rp.robot: len(rp.path) // 2 for rp in plan.robots},
                                   {2})
    return plan, covered, survivors


def assert_a_replan(plan: Plan, covered: np.ndarray, survivors: list[Survivor],
                    replan: Replan) -> None:
    """Every uncovered sub-cell has one live owner on whose route it lies, and each route is
    a walk of 4-adjacent moves from where its survivor stands."""
    alive = {s.robot for s in survivors}
    assert set(replan.owner) == set(np.flatnonzero(~covered).tolist())
    assert set(replan.owner.values()) <= alive and set(replan.routes) == alive
    for index, robot in replan.owner.items():
        assert index in replan.routes[robot]
    at = {s.robot: s.position for s in survivors}
    for robot, route in replan.routes.items():
        check_path_moves([plan.cycle.at(i) for i in (at[robot], *route)])


@pytest.mark.parametrize("seed", range(6))
def test_every_uncovered_sub_cell_has_one_live_owner_on_whose_route_it_lies(seed: int) -> None:
    plan, covered, survivors = snapshot(seed)
    assert_a_replan(plan, covered, survivors,
                    rebalance(plan.cycle, covered, survivors, plan_order(plan)))


def test_the_replan_depends_only_on_its_inputs() -> None:
    plan, covered, survivors = snapshot(3)
    rank = plan_order(plan)
    first = rebalance(plan.cycle, covered, survivors, rank)
    again = rebalance(plan.cycle, covered.copy(), list(reversed(survivors)), rank.copy())
    assert first == again


@pytest.mark.slow  # 4-5 s each (the quick loop stays near a minute)
@pytest.mark.parametrize("algo", ("opt", "balanced"))
def test_rebalancing_beats_the_takeover_on_seeded_instances(algo: str) -> None:
    """One death at 30 % coverage on generated instances: rebalancing finishes first on
    average, and never later than the takeover."""
    ratios = []
    for seed in range(10):
        area = generated(100 + seed, 6)
        plan = make(algo, area, seed)
        replay = algorithm(algo).load_lockstep()
        first = replay(plan, {}).first_time
        times = np.sort(first[first >= 0])
        at = int(times[int(0.3 * times.size)])
        dead = plan.robots[seed % plan.k].robot
        took, rebalanced = (replay(plan, {dead: at}, recovery=r) for r in RECOVERIES)
        assert took.complete and rebalanced.complete
        assert rebalanced.coverage_time is not None and took.coverage_time is not None
        assert rebalanced.coverage_time <= took.coverage_time, seed
        ratios.append(rebalanced.coverage_time / took.coverage_time)
    assert statistics.mean(ratios) < 0.85


def unrefined(grid: Grid, covered: np.ndarray, survivors: list[Survivor],
              chosen: Replan) -> Replan:
    return chosen


@pytest.mark.slow  # 4-5.5 s each (the quick loop stays near a minute)
@pytest.mark.parametrize(("switch", "off", "at_least"), [
    ("_greedy_split", lambda *_, **__: None, 2),
    ("REGROW_MAX_SUB_CELLS", 0, 3),
    ("_refined", unrefined, 5),
])
def test_each_kind_of_replan_never_lengthens_the_replan_and_shortens_some(
        switch: str, off: object, at_least: int) -> None:
    """The re-plan keeps an option only when it finishes first, so with it switched off no
    re-plan of these snapshots is shorter, and with it some are. planner.stretches' greedy
    (it sizes each piece to what its taker can do): measured 3 of 12, one move each; the
    regrown regions (planner.balanced.regrow): 5 of 12, by 1-5 moves (both unrefined: a
    refinement of another option may win either way); the refinement of the options
    (planner.offline.refine): 6 of 12, by 1-20 moves."""
    shorter = 0
    for seed in range(12):
        plan, covered, survivors = snapshot(seed)
        rank = plan_order(plan)
        with pytest.MonkeyPatch.context() as patch:
            if switch != "_refined":
                patch.setattr(rebalance_module, "_refined", unrefined)
            with_it = rebalance(plan.cycle, covered, survivors, rank)
            patch.setattr(rebalance_module, switch, off)
            without = rebalance(plan.cycle, covered, survivors, rank)
        assert with_it.makespan <= without.makespan, seed
        shorter += with_it.makespan < without.makespan
    assert shorter >= at_least


@pytest.mark.slow  # about 4 s (a 12 668 sub-cell plan and two re-plans)
def test_a_large_area_is_refined_too_and_that_shortens_its_replan() -> None:
    """Above 12 000 sub-cells the chosen re-plan was not refined (REFINE_MAX_SUB_CELLS). On
    city 64 x 64 (12 668 sub-cells), 30 robots at uneven progress (each 20-60 % through its
    walk, as a fleet at time scale 0 moves) and one dead, the refinement shortens it (334 ->
    304 moves when written), and it stays a re-plan: every uncovered sub-cell has one live
    owner on whose route it lies, and the routes are walks."""
    grid = resolve_world("city:64x64:3")
    area = work_area(grid, random_starts(grid, 30, 2))
    assert area.n > 12_000
    plan = make("balanced", area, 2)
    rng = random.Random(2)
    walked = {rp.robot: int(len(rp.path) * rng.uniform(0.2, 0.6)) for rp in plan.robots}
    covered, survivors = frozen_at(plan, walked, {rng.randrange(30)})
    rank = plan_order(plan)
    refined = rebalance(plan.cycle, covered, survivors, rank)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(rebalance_module, "REFINE_MAX_SUB_CELLS", 12_000)
        unrefined_replan = rebalance(plan.cycle, covered, survivors, rank)
    assert refined.makespan < unrefined_replan.makespan
    assert_a_replan(plan, covered, survivors, refined)


def masked(seed: int) -> Cycle:
    """A grid of sub-cells 40 % blocked at random (Grid only needs each free sub-cell's
    index, not a real STC cycle): walks wind, so near places can be far apart."""
    free = np.random.default_rng(seed).random((40, 40)) > 0.4
    path = np.argwhere(free)
    index = np.full(free.shape, -1)
    index[free] = np.arange(len(path))
    return Cycle(path, index)


@pytest.mark.slow  # over 4 s (the quick loop stays near a minute)
@pytest.mark.parametrize("all_pairs", [True, False], ids=["table", "windows"])
def test_the_windowed_searches_give_shortest_distances_and_paths(
        all_pairs: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """Grid searches a window round two near places first (planner.offline.shortest.Grid).
    From two sources of one winding grid (seed 2) to every place within NEAR: every
    distance equals the whole-grid search's, every path is that long, a walk of 4-adjacent
    moves, and it goes round a sub-cell avoided when it can. Source 642 has places the
    window reaches only the long way round (checked): the whole grid must take over. The
    grid's 968 places are few enough for the table of every distance; without it
    (``windows``) the distances come from the searches."""
    if not all_pairs:
        monkeypatch.setattr(shortest, "ALL_PAIRS_MAX", 0)
    cycle = masked(2)
    tabled = Grid(cycle)  # with the table, one Grid: its table is all that it holds
    window_alone_wrong = 0
    for a in (642, 1000):
        searcher, whole = Grid(cycle), Grid(cycle).from_source(a)
        ra, ca = cycle.at(a)
        for b in range(cycle.n):
            rb, cb = cycle.at(b)
            if abs(ra - rb) + abs(ca - cb) > NEAR or whole[rb, cb] >= FAR:
                continue
            box, _ = searcher._window(a, b)
            inside = searcher._bfs(a, frozenset(), box)[rb - box[0], cb - box[2]]
            window_alone_wrong += bool(inside < FAR and inside != whole[rb, cb])
            fresh = tabled if all_pairs else Grid(cycle)  # the searches: nothing cached
            assert fresh.distance(a, b) == whole[rb, cb]
            path = searcher.path(a, b)
            assert len(path) == whole[rb, cb] and (not path or path[-1] == b)
            check_path_moves([cycle.at(i) for i in (a, *path)])
            if len(path) > 2 and b % 21 == 0:  # block one sub-cell of it: go round if one can
                avoid = frozenset({path[len(path) // 2]})
                around = Grid(cycle).from_source(a, avoid)
                detour = searcher.path(a, b, avoid)
                check_path_moves([cycle.at(i) for i in (a, *detour)])
                if around[rb, cb] < FAR:
                    assert len(detour) == around[rb, cb] and not avoid & set(detour)
    assert window_alone_wrong >= 3


def test_a_small_map_s_table_of_distances_agrees_with_the_searches(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """On a map of at most ALL_PAIRS_MAX places every distance is found at once: from each
    of a few sources (one in a pocket of its own) to every place it equals the whole-grid
    breadth-first search (FAR where none leads), and ``distances`` gives the same matrix
    with the table as without it."""
    cycle = masked(3)
    assert cycle.n <= shortest.ALL_PAIRS_MAX
    maps = Grid(cycle)
    sources = [0, 17, cycle.n // 2, cycle.n - 1]
    places = list(range(cycle.n))
    table = maps.distances(sources, places)
    for row, a in zip(table, sources, strict=True):
        whole = Grid(cycle).from_source(a)
        assert row.tolist() == [int(whole[tuple(cycle.at(b))]) for b in places]
    assert (table >= FAR).any() and (table < FAR).any()  # some places are cut off
    monkeypatch.setattr(shortest, "ALL_PAIRS_MAX", 0)
    assert np.array_equal(Grid(cycle).distances(sources, places[::7]), table[:, ::7])


def test_with_nothing_orphaned_the_routes_are_kept_when_no_cut_is_shorter() -> None:
    """A robot that dies after its own route leaves no orphans. Cutting all the work anew
    among the nearest MAX_TAKERS survivors is then no re-plan to take blindly: 16
    survivors of a balanced plan on office at their starts (the dead robot's region
    covered) would finish later than their own routes (measured: 69 against 54 moves)."""
    grid = resolve_world("office")
    area = work_area(grid, random_starts(grid, 17, 4))
    plan = make("balanced", area, 4)
    cycle = plan.cycle
    covered = np.zeros(cycle.n, dtype=bool)
    survivors = []
    for rp in plan.robots[:-1]:  # the last robot: dead with nothing left to do
        walk = [cycle.position(s) for s in rp.path]
        covered[walk[0]] = True
        survivors.append(Survivor(rp.robot, walk[0], tuple(walk[1:])))
    covered[[cycle.position(s) for s in plan.robots[-1].path]] = True
    replan = rebalance(cycle, covered, survivors, plan_order(plan))
    assert replan.makespan <= max(len(s.route) for s in survivors)
