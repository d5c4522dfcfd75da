"""ORMSTC end to end in the lockstep simulator, checked against world-only oracles.

Random worlds have obstacles at sub-cell level (so some cells are partly blocked and must be
skipped). Oracles: the reachable free cells (tests/ormstc_oracles.py), the offline STC cycle of
each robot's own tree (planner.cycle.stc_cycle), and ground-truth ownership from the
simulator's log of tree edges.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import assume, event, given, settings
from hypothesis import strategies as st
from ormstc_oracles import missed, must_cover

from planner.cycle import stc_cycle
from planner.errors import RobotPlacementError
from planner.grid import coarsen, largest_component
from planner.ormstc.lockstep import SimConfig, SimResult, simulate
from planner.ormstc.types import Priority, SenseMode
from planner.types import OccupancyGrid, SpanningTree, SubCell


def random_world(seed: int, h: int, w: int, density: float) -> OccupancyGrid:
    rng = np.random.default_rng(seed)
    free = rng.random((2 * h, 2 * w)) >= density
    return OccupancyGrid(free, name=f"random-{seed}")


def random_starts(world: OccupancyGrid, k: int, seed: int) -> list[SubCell]:
    rng = np.random.default_rng(seed + 1)
    cells = np.argwhere(largest_component(coarsen(world)))
    pick = rng.choice(len(cells), size=min(k, len(cells)), replace=False)
    return [(2 * int(cells[i][0]) + int(rng.integers(2)), 2 * int(cells[i][1])
             + int(rng.integers(2))) for i in pick]


worlds = st.builds(random_world, st.integers(0, 10**6), st.integers(2, 9), st.integers(2, 9),
                   st.sampled_from([0.0, 0.05, 0.1, 0.15]))


def tree_of(result: SimResult, robot: int, shape: tuple[int, int]) -> SpanningTree:
    cells = np.zeros(shape, dtype=bool)
    right = np.zeros(shape, dtype=bool)
    down = np.zeros(shape, dtype=bool)
    s = result.starts[robot]
    cells[s[0] // 2, s[1] // 2] = True
    for a, b in result.trees[robot]:
        cells[a] = cells[b] = True
        (r0, c0), (r1, _c1) = sorted((a, b))
        if r0 == r1:
            right[r0, c0] = True
        else:
            down[r0, c0] = True
    return SpanningTree(cells=cells, right=right, down=down)


def check_moves_are_legal(result: SimResult) -> None:
    free = result.world.free
    for path in result.paths:
        steps = np.abs(np.diff(np.asarray(path).reshape(-1, 2), axis=0)).sum(axis=1)
        assert (steps == 1).all()
        assert all(free[p] for p in path)


@settings(max_examples=30, deadline=None)
@given(world=worlds, k=st.integers(1, 5), seed=st.integers(0, 1000))
def test_complete_and_non_redundant_without_failures(world: OccupancyGrid, k: int,
                                                     seed: int) -> None:
    starts = random_starts(world, k, seed)
    result = simulate(world, starts, SimConfig(seed=seed))
    assert result.finished
    check_moves_are_legal(result)
    need = must_cover(world, starts)
    assert not (need & ~result.covered).any()
    # every sub-cell once, except each robot's start, entered again when it comes home
    home = np.zeros_like(result.visits)
    for s in starts:
        home[s] = 1
    assert (result.visits - home <= 1).all()
    assert not result.conflicts
    assert set(result.done_steps) == set(range(len(starts)))  # everyone saw the end


@settings(max_examples=20, deadline=None)
@given(world=worlds, k=st.integers(1, 4), seed=st.integers(0, 1000))
def test_each_path_is_the_stc_cycle_of_its_own_tree(world: OccupancyGrid, k: int,
                                                    seed: int) -> None:
    starts = random_starts(world, k, seed)
    assume(starts)  # a world without a free cell has no tree to check
    result = simulate(world, starts, SimConfig(seed=seed, delay=(1, 3)))
    shape = coarsen(world).shape
    owned = np.zeros(shape, dtype=np.int64)
    for robot, start in enumerate(starts):
        tree = tree_of(result, robot, shape)
        owned += tree.cells
        cycle = stc_cycle(tree, start=start)
        expected = [cycle.at(i) for i in range(cycle.n)] + [start]
        assert list(result.paths[robot]) == expected
    assert owned.max() == 1  # the trees are disjoint


@settings(max_examples=30, deadline=None)
@given(world=worlds, k=st.integers(2, 5), seed=st.integers(0, 1000), data=st.data())
def test_robust_to_up_to_k_minus_one_failures(world: OccupancyGrid, k: int, seed: int,
                                              data: st.DataObject) -> None:
    starts = random_starts(world, k, seed)
    k = len(starts)
    if k < 2:
        return
    victims = data.draw(st.lists(st.integers(0, k - 1), min_size=1, max_size=k - 1,
                                 unique=True))
    # Failure steps sized to the world: a robot's share of the sub-cells, so that most victims
    # die with work left (a fixed 0..150 let a third of them die after they were done).
    share = max(1, int(world.free.sum()) // k)
    steps = data.draw(st.lists(st.integers(0, share), min_size=len(victims),
                               max_size=len(victims)))
    failures = tuple(zip(victims, steps, strict=True))
    config = SimConfig(seed=seed, delay=(1, 3), failures=failures,
                       detect_delay=data.draw(st.integers(1, 5)))
    result = simulate(world, starts, config)
    assert result.finished
    check_moves_are_legal(result)
    assert not missed(result).any()
    assert not result.conflicts
    busy = sum(victim in result.deaths and victim not in result.done_steps
               for victim in victims)
    event(f"victims that died with work left: {'all' if busy == len(victims) else busy}")


@settings(max_examples=25, deadline=None)
@given(world=worlds, k=st.integers(2, 6), seed=st.integers(0, 1000),
       delay=st.tuples(st.integers(1, 3), st.integers(3, 8)),
       priority=st.sampled_from(list(Priority)))
def test_no_cell_has_two_live_owners_under_random_delays(
        world: OccupancyGrid, k: int, seed: int, delay: tuple[int, int],
        priority: Priority) -> None:
    starts = random_starts(world, k, seed)
    result = simulate(world, starts, SimConfig(seed=seed, delay=delay, priority=priority))
    assert result.finished
    assert not result.conflicts
    assert not (must_cover(world, starts) & ~result.covered).any()


def test_a_too_short_claim_wait_is_caught_by_the_ownership_oracle() -> None:
    # the same oracle fails when the settle window is below the proven bound
    found = False
    for seed in range(40):
        world = random_world(seed, 6, 6, 0.0)
        starts = random_starts(world, 6, seed)
        result = simulate(world, starts, SimConfig(seed=seed, delay=(1, 6), claim_wait=1))
        if result.conflicts:
            found = True
            break
    assert found


def test_unknown_bounds_large_room_robots_in_a_corner() -> None:
    world = OccupancyGrid(np.ones((80, 90), dtype=bool), name="big-room")
    starts = [(0, 0), (0, 3), (3, 1)]
    result = simulate(world, starts, SimConfig(seed=3))
    assert result.finished
    assert result.covered.all()
    assert int(result.visits.sum()) == world.free.size + len(starts)


@settings(max_examples=15, deadline=None)
@given(world=worlds, k=st.integers(1, 4), seed=st.integers(0, 1000))
def test_sensing_modes_cover_the_same_sub_cells(world: OccupancyGrid, k: int,
                                                seed: int) -> None:
    starts = random_starts(world, k, seed)
    every = simulate(world, starts, SimConfig(seed=seed, sense_mode=SenseMode.ALL))
    single = simulate(world, starts, SimConfig(seed=seed, sense_mode=SenseMode.SINGLE))
    assert (every.covered == single.covered).all()
    assert sum(every.sense_turns) == 0
    # One sonar at a time: each side the robot does not face costs a turn there and back.
    assert all(turns % 2 == 0 for turns in single.sense_turns)
    # With more cells than robots someone leaves its start cell, and it looks at the cells
    # around a cell one at a time, at most one of them straight ahead.
    if int(largest_component(coarsen(world)).sum()) > k:
        assert sum(single.sense_turns) > 0


def test_start_off_a_sub_cell_centre_snaps_first() -> None:
    from planner.ormstc.machine import OrmstcMachine
    from planner.ormstc.types import MachineConfig, Move

    machine = OrmstcMachine(MachineConfig(robot=0, team=1, start=(2.4, 3.6)))
    first = machine.step(())
    assert first == [Move((2, 4))]


def test_two_robots_in_one_cell_is_a_placement_error() -> None:
    world = OccupancyGrid(np.ones((6, 6), dtype=bool))
    with pytest.raises(RobotPlacementError):
        simulate(world, [(0, 0), (1, 1)])
