"""Connected coverage of trees by a team that must stay connected (paper 001: NCOCTA, COCTA).

Robots sit on tree nodes and may talk only to robots on the same or an adjacent node, so the
nodes they occupy must always induce one connected subtree. Everything here is pure: trees in,
coverage results out.
"""

from planner.treecover.sim import run_coverage
from planner.treecover.trees import general_tree, load_tree, office_tree, perfect_tree
from planner.treecover.types import CoverageResult, Splits, Tree

__all__ = [
    "CoverageResult",
    "Splits",
    "Tree",
    "general_tree",
    "load_tree",
    "office_tree",
    "perfect_tree",
    "run_coverage",
]
