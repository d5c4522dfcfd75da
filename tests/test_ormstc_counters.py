"""The ORMSTC machine's move counter against the lockstep simulator's ground truth: it is what
the agents report (AgentState's moves, the `completed` line), so an off-by-one there is a wrong
figure in every report."""

from __future__ import annotations

import numpy as np
import pytest

from planner.ormstc.lockstep import LockstepSim, SimConfig
from planner.types import OccupancyGrid

ROOM = OccupancyGrid(np.ones((10, 12), dtype=bool), name="room")
STARTS = [(0, 0), (9, 11), (0, 11)]


@pytest.mark.parametrize("failures", [(), ((1, 3),), ((1, 3), (2, 5)), ((0, 40),)])
def test_each_survivor_counts_the_moves_its_path_shows(failures: tuple[tuple[int, int], ...]
                                                      ) -> None:
    sim = LockstepSim(ROOM, STARTS, SimConfig(seed=1, failures=failures))
    result = sim.run()
    assert result.finished
    # A robot that died may have a move in flight (made, never reported back to its machine).
    survivors = [r for r in range(len(STARTS)) if r not in result.deaths]
    assert [sim.machines[r].moves for r in survivors] == [result.moves[r] for r in survivors]
    assert sum(result.moves[r] for r in survivors) > 0
