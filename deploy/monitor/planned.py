"""An offline fleet's spanning tree, rebuilt from what the wire says: the map (simhw's
WorldState), the starts (RobotStatus) and the tree kind and seed (AgentState). Agents never
send their plan; each computes it from these inputs (agent/plan.py), so the monitor can too,
and a late joiner draws the whole tree, not only the edges walked since it joined."""

from __future__ import annotations

from collections.abc import Sequence

from planner.geometry import cell_of
from planner.grid import work_area
from planner.trees import build_tree
from planner.types import BoolArray, Cell, OccupancyGrid, SubCell

Edge = tuple[Cell, Cell]


def planned_edges(free: BoolArray, starts: Sequence[SubCell], kind: str,
                  seed: int) -> frozenset[Edge]:
    """The tree edges (first cell above or left of the second) the agents plan along;
    PlannerError if the inputs make no plan (the agents then refuse to start too)."""
    area = work_area(OccupancyGrid(free), starts)
    tree = build_tree(area.cells, kind, seed=seed, starts=[cell_of(s) for s in starts])
    return frozenset(tree.edges())
