"""Balanced planner (issue 7): connected regions of near-equal size, one STC walk per robot.

``balanced_plan(area, seed=...)`` plans; ``partition`` gives the regions;
``planner.balanced.takeover.simulate_failures`` replays a plan with fail-stop robots and the
ring takeover rule. Robots boxed in by others' start cells may walk out to a region first.
docs/balanced.md has the design, the measurements and the commands that made them.
"""

from planner.balanced.plan import ALGO, balanced_plan
from planner.balanced.regions import partition
from planner.balanced.types import LeafCell, Partition, Region

__all__ = ["ALGO", "LeafCell", "Partition", "Region", "balanced_plan", "partition"]
