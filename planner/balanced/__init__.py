"""Balanced planner (issue 7): connected regions of near-equal size, one STC walk per robot.

``balanced_plan(area, seed=...)`` plans; ``partition`` gives the regions;
``planner.balanced.takeover.simulate_failures`` replays a plan with fail-stop robots and the
ring takeover rule. Robots boxed in by others' start cells may walk out to a region first.
docs/balanced.md has the design, the measurements and the commands that made them.

The names below load on first use: an agent that flies a plan shared with it imports
``planner.balanced.machine`` only, and the planner behind ``balanced_plan`` (scipy's
assignment, sparse graphs and flows: 0.9 s of imports) would otherwise come with it. 100
agents importing it at once on 2 cores kept a fleet from moving for 20 s (2026-12-05).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from planner.balanced.plan import ALGO, balanced_plan
    from planner.balanced.regions import partition
    from planner.balanced.types import LeafCell, Partition, Region

_HOMES = {"ALGO": "planner.balanced.plan", "balanced_plan": "planner.balanced.plan",
          "partition": "planner.balanced.regions", "LeafCell": "planner.balanced.types",
          "Partition": "planner.balanced.types", "Region": "planner.balanced.types"}

__all__ = ["ALGO", "LeafCell", "Partition", "Region", "balanced_plan", "partition"]


def __getattr__(name: str) -> Any:
    home = _HOMES.get(name)
    if home is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(home), name)
