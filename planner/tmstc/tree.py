"""The TMSTC* spanning tree: minimum brick tiling, greedy merge, then our swap pass."""

from __future__ import annotations

import numpy as np

from planner.tmstc.improve import improve_turns
from planner.tmstc.merge import merge_bricks
from planner.tmstc.tiling import brick_tiling
from planner.tmstc.turns import tree_turns
from planner.types import BoolArray, SpanningTree


def tmstc_tree(cells: BoolArray, *, seed: int = 0, tries: int = 1,
               improve: bool = True) -> SpanningTree:
    """A spanning tree of ``cells`` (one 4-connected component) with few cycle turns.

    ``tries`` greedy merges with different seeded tie-breaks are made and the one with the
    fewest turns kept; ``improve`` adds the edge-swap pass (paper: ``tries=1, improve=False``).
    """
    tiling = brick_tiling(np.asarray(cells, dtype=bool))
    best: SpanningTree | None = None
    best_turns = 0
    for attempt in range(max(1, tries)):
        tree = merge_bricks(tiling, seed=seed * 7919 + attempt)
        if improve:
            tree = improve_turns(tree)
        turns = tree_turns(tree)
        if best is None or turns < best_turns:
            best, best_turns = tree, turns
    assert best is not None
    return best
