"""Shared hypothesis strategies of the tree-coverage tests."""

from __future__ import annotations

import numpy as np
from hypothesis import strategies as st

from planner.treecover.trees import from_parents
from planner.treecover.types import Tree

ALGOS = ["ncocta", "cocta"]


@st.composite
def random_trees(draw: st.DrawFn) -> Tree:
    """Any rooted tree of 1-40 nodes: each node hangs off a random earlier one."""
    n = draw(st.integers(1, 40))
    parent = [-1] + [draw(st.integers(0, i - 1)) for i in range(1, n)]
    return from_parents(np.array(parent))
