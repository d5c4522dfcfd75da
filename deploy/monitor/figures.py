"""The figures of a mission, defined once: what ``mstc up``'s summary, ``mstc report`` and
``mstc monitor`` print about the same run are read off a FleetModel by this one function, so
they cannot disagree on the same messages.

- makespan: the most moves any robot had made when the last reachable sub-cell was first
  covered (until then: the most moves so far);
- simulated seconds: from the first covered sub-cell to the one that completed the coverage
  (until then: to the latest simulated time heard);
- revisits: visits of a sub-cell beyond its first, over all sub-cells.
"""

from __future__ import annotations

from dataclasses import dataclass

from deploy.monitor.model import FleetModel


@dataclass(frozen=True)
class MissionFigures:
    makespan_moves: int
    total_moves: int  # all robots' moves so far (after the coverage too)
    sim_seconds: float
    coverage_sim_seconds: float | None  # None while the coverage is not complete
    coverage_wall_seconds: float | None
    revisits: int
    revisited_cells: int  # sub-cells entered more than once


def mission_figures(model: FleetModel) -> MissionFigures:
    moves = [v.moves for v in model.robots.values()]
    at_coverage = model.moves_at_coverage
    first_sim = min((s for _, s, _ in model.cover.curve), default=0.0)
    complete = model.cover.complete_at
    coverage_sim = None if complete is None else round(complete[1] - first_sim, 6)
    return MissionFigures(
        makespan_moves=max(at_coverage.values() if at_coverage is not None else moves,
                           default=0),
        total_moves=sum(moves),
        sim_seconds=coverage_sim if coverage_sim is not None else
        max(0.0, model.sim_time - first_sim),
        coverage_sim_seconds=coverage_sim,
        coverage_wall_seconds=None if complete is None else round(complete[0], 6),
        revisits=model.revisits(),
        revisited_cells=sum(1 for n in model.covered_cells().values() if n > 1))
