"""The figures of a mission, defined once: what ``mstc up``'s summary, ``mstc report`` and
``mstc monitor`` print about the same run are read off a FleetModel by this one function, so
they cannot disagree on the same messages.

- makespan: the most moves any robot had made when the last reachable sub-cell was first
  covered (until then: the most moves so far);
- simulated seconds: from the first covered sub-cell to the one that completed the coverage
  (until then: to the latest simulated time heard);
- revisits: visits of a sub-cell beyond its first, over all sub-cells.

It is also the one home of the figures' styling: each robot's colour, the same in the live
view, the report's and the plan's pictures and the robotics channels.
"""

from __future__ import annotations

import colorsys
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


# Hue step of the golden ratio: neighbouring ids get hues far apart (3 and 4 differ as much
# as 3 and 30) and no hue comes back; the brightness also steps through three levels, so the
# ids whose hues come closest (Fibonacci distances apart, 21 for instance) still differ.
GOLDEN = 0.381966
_VALUES = (0.95, 0.78, 0.62)
Rgba = tuple[float, float, float, float]


def robot_colour(robot: int, alpha: float = 1.0) -> Rgba:
    """Robot ``robot``'s colour as RGBA in 0..1."""
    r, g, b = colorsys.hsv_to_rgb((robot * GOLDEN) % 1.0, 0.85, _VALUES[robot % len(_VALUES)])
    return (r, g, b, alpha)


def robot_hex(robot: int) -> str:
    """Robot ``robot``'s colour as ``#rrggbb`` (matplotlib and rich both take it)."""
    r, g, b, _ = robot_colour(robot)
    return f"#{round(255 * r):02x}{round(255 * g):02x}{round(255 * b):02x}"

