"""TMSTC* end to end: turn-minimising tree, then the time-balanced division of its cycle."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planner.metrics import KOBUKI, KinematicParams
from planner.tmstc.division import divide
from planner.tmstc.tree import tmstc_tree
from planner.tmstc.types import Division
from planner.types import BoolArray, SpanningTree, SubCell


def tmstc_plan(cells: BoolArray, starts: Sequence[SubCell], *, seed: int = 0, tries: int = 1,
               improve: bool = True, balance: str = "time",
               params: KinematicParams = KOBUKI) -> tuple[SpanningTree, Division]:
    """The TMSTC* tree of ``cells`` and its cycle split among robots at ``starts``."""
    tree = tmstc_tree(np.asarray(cells, dtype=bool), seed=seed, tries=tries, improve=improve)
    return tree, divide(tree, starts, balance=balance, params=params)
