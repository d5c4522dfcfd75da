"""ORMSTC robustness with failure steps sized to the world: victims die while they still have
work (issue 15: steps drawn from 0..150 whatever the world's size left a third of the cases
with nothing to take over). hypothesis.event reports where in their walks they die."""

from __future__ import annotations

from hypothesis import assume, event, given, settings
from hypothesis import strategies as st
from ormstc_oracles import missed
from test_ormstc_sim import check_moves_are_legal, random_starts, worlds

from planner.ormstc.lockstep import SimConfig, simulate
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
