"""Oracles for the ORMSTC tests: what must be covered, computed from the world alone."""

from __future__ import annotations

from collections.abc import Callable, Generator, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from planner.grid import coarsen, expand, label_components
from planner.ormstc.lockstep import LockstepSim, SimConfig, SimResult
from planner.ormstc.types import Priority
from planner.types import BoolArray, OccupancyGrid, SubCell


def must_cover(world: OccupancyGrid, starts: Sequence[SubCell],
               blocked_subs: Sequence[SubCell] = ()) -> BoolArray:
    """Sub-cells of the free cells reachable (4-connected, on the coarse grid) from a start.

    ``blocked_subs`` (dead bodies) make their cells impassable, and reachability then counts
    only from the starts in cells still passable.
    """
    free = coarsen(world).free.copy()
    for r, c in blocked_subs:
        free[r // 2, c // 2] = False
    labels, _ = label_components(free)
    keep = {int(labels[r // 2, c // 2]) for r, c in starts} - {0}
    cells = np.isin(labels, list(keep))
    out = np.zeros(world.shape, dtype=bool)
    mask = expand(cells)
    out[: mask.shape[0], : mask.shape[1]] = mask
    return out


def body_positions(result: SimResult) -> list[SubCell]:
    """Where the dead robots' bodies stopped."""
    return [result.paths[robot][-1] for robot in result.deaths]


def survivors_starts(result: SimResult) -> list[SubCell]:
    return [s for i, s in enumerate(result.starts) if i not in result.deaths]


def missed(result: SimResult) -> BoolArray:
    """Sub-cells the oracle requires that nobody covered."""
    need = must_cover(result.world, survivors_starts(result), body_positions(result))
    return need & (result.visits == 0)


WalkStep = Callable[[Any, SubCell, SubCell], Generator[Any, object, bool]]


def never_giving_up(step: WalkStep) -> WalkStep:
    """``passage.walk_step`` as it was before bodies for good were recognised: it tries
    again until it gets there (the counterfactual of the pinned runs that hung so)."""
    def again(m: Any, to: SubCell, target: SubCell) -> Generator[Any, object, bool]:
        while not (yield from step(m, to, target)):
            pass
        return True
    return again


def forced_with_deaths(seed: int, priority: Priority, deaths: tuple[tuple[int, int], ...],
                       *, half_sense: bool) -> SimConfig:
    """The lockstep of ``bench_forced_collisions.py --wide --deaths``: a claim window of one
    step (claims collide), message delays of 1-6 steps, robots dying at given steps."""
    return SimConfig(seed=seed, delay=(1, 6), claim_wait=1, priority=priority, failures=deaths,
                     half_sense=half_sense)


def check_the_rule_ends_it(world: OccupancyGrid, starts: Sequence[SubCell], config: SimConfig,
                           take_away: Callable[[], None]) -> None:
    """A pinned run ends with nothing missed; with its rule taken away (``take_away``, a
    monkeypatch) the same run does not end within 2 000 steps more: the check can fail."""
    result = LockstepSim(world, starts, config).run()
    assert result.finished and not missed(result).any()
    take_away()
    stuck = LockstepSim(world, starts, replace(config, max_steps=result.steps + 2_000)).run()
    assert not stuck.finished
