"""ORMSTC robustness with failure steps sized to the world: victims die while they still have
work (issue 15: steps drawn from 0..150 whatever the world's size left a third of the cases
with nothing to take over). hypothesis.event reports where in their walks they die."""

from __future__ import annotations

from dataclasses import replace

import pytest
from hypothesis import assume, event, given, settings
from hypothesis import strategies as st
from ormstc_oracles import missed
from test_ormstc_sim import check_moves_are_legal, random_starts, random_world, worlds

from planner.ormstc import passage
from planner.ormstc.claims import ClaimBook
from planner.ormstc.lockstep import SimConfig, simulate
from planner.ormstc.types import Priority
from planner.types import OccupancyGrid


@settings(max_examples=30, deadline=None)
@given(world=worlds, k=st.integers(2, 5), seed=st.integers(0, 1000), data=st.data())
def test_robust_to_failures_while_the_victims_still_have_work(
        world: OccupancyGrid, k: int, seed: int, data: st.DataObject) -> None:
    starts = random_starts(world, k, seed)
    assume(len(starts) >= 2)
    k = len(starts)
    clean = simulate(world, starts, SimConfig(seed=seed, delay=(1, 3)))
    assert clean.finished
    # A robot's own walk in the failure-free run bounds when it can still die with work left.
    lengths = [len(path) - 1 for path in clean.paths]
    victims = data.draw(st.lists(st.integers(0, k - 1), min_size=1, max_size=k - 1,
                                 unique=True))
    steps = [data.draw(st.integers(0, max(lengths[v] - 1, 0))) for v in victims]
    for v, step in zip(victims, steps, strict=True):
        # steps are time steps and a move takes at least one: the victim dies with work left
        event(f"victim dies in the {'first' if 2 * step < lengths[v] else 'second'} half")
    config = SimConfig(seed=seed, delay=(1, 3), failures=tuple(zip(victims, steps, strict=True)),
                       detect_delay=data.draw(st.integers(1, 5)))
    result = simulate(world, starts, config)
    assert result.finished
    check_moves_are_legal(result)
    assert not missed(result).any()
    assert not result.conflicts


# (seed, cells a side, robots, priority, deaths): every run of 4 000 with deaths and the safe
# claim window (benchmarks/bench_forced_collisions.py --wide --deaths --safe-window) that never
# ended before a won claim looked again at a cell a dead rival had claimed: the rival won it,
# stepped in and died before its tree edge came, and the next robot grew into the cell and
# waited for ever behind the body.
_RIVAL_DIED_INSIDE = [
    (1252, 6, 6, Priority.FEWEST, ((5, 56),)),
    (1396, 4, 6, Priority.ID, ((3, 56), (4, 52), (2, 16))),
    (344, 7, 6, Priority.FEWEST, ((5, 110), (4, 67), (2, 84), (1, 110), (3, 105))),
    (2038, 4, 6, Priority.ID, ((4, 44), (5, 7), (0, 38), (3, 12), (2, 41))),
]


@pytest.mark.parametrize(("seed", "size", "k", "priority", "deaths"), _RIVAL_DIED_INSIDE)
def test_a_cell_a_dead_rival_claimed_is_looked_at_again_before_it_is_entered(
        seed: int, size: int, k: int, priority: Priority,
        deaths: tuple[tuple[int, int], ...]) -> None:
    world = random_world(seed, size, size, 0.0)
    starts = random_starts(world, k, seed)
    config = SimConfig(seed=seed, delay=(1, 6), priority=priority, failures=deaths)
    result = simulate(world, starts, config)
    assert result.finished
    check_moves_are_legal(result)
    assert not missed(result).any()
    with pytest.MonkeyPatch.context() as patch:
        # the rule switched off (and the last resort of walking round a body in a cell of
        # one's own, planner/ormstc/passage.py, which gets such a robot out too): never ends
        patch.setattr(ClaimBook, "claimed_by_any", lambda *_args: False)
        patch.setattr(passage, "STUCK_AFTER", 10**9)
        stuck = simulate(world, starts, replace(config, max_steps=result.steps + 2_000))
    assert not stuck.finished
