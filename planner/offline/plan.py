"""The offline MSTC pipeline (paper 003, Alg. 1): cycle from robot 0's start, allocate, plan."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planner.allocation import allocate
from planner.cycle import stc_cycle
from planner.errors import RobotPlacementError
from planner.grid import WorkArea
from planner.offline.build import build_plan
from planner.types import Plan, SpanningTree


def make_plan(area: WorkArea, tree: SpanningTree, algo: str, *,
              speeds: Sequence[float] | None = None,
              fuel: Sequence[int | None] | None = None) -> Plan:
    """Plan ``algo`` (nb, bt, opt) for the robots of ``area`` along the STC cycle of ``tree``.

    ``tree`` must span exactly the work-area's cells (ValueError otherwise: a tree of other
    cells is a programming mistake, not a user one).
    """
    if tree.cells.shape != area.cells.shape or not np.array_equal(tree.cells, area.cells):
        raise ValueError("the spanning tree does not span the work-area's cells")
    if not area.starts:
        raise RobotPlacementError("no robots given")
    cycle = stc_cycle(tree, start=area.starts[0])
    positions = [cycle.position(s) for s in area.starts]
    allocations = allocate(algo, cycle.n, positions, speeds=speeds, fuel=fuel)
    return build_plan(algo, cycle, area.starts, allocations, speeds=speeds, tree=tree)


def plan_for(area: WorkArea, tree: SpanningTree, algo: str, seed: int = 0) -> Plan:
    """The registry's entry point (planner.algorithms): ``seed`` only seeds the tree."""
    del seed
    return make_plan(area, tree, algo)
