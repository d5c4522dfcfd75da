"""The balanced planner's revisit promise checked on a record: every sub-cell is entered once
except by moves that only lead a robot to its region (its walk-out).

How long each robot's walk-out is comes from the plan itself, made again from what the record
holds (the world, each robot's start, the seed and tree kind its agent announced): the
planner is pure and deterministic, and the agents compared digests of that very plan.
"""

from __future__ import annotations

from collections import Counter

from deploy.monitor.model import FleetModel
from planner.algorithms import algorithm
from planner.errors import PlannerError
from planner.geometry import cell_of
from planner.grid import work_area
from planner.trees import build_tree
from planner.types import OccupancyGrid, SubCell


def walk_out_moves(model: FleetModel, algo: str) -> dict[int, int] | str:
    """Each robot's planned walk-out moves, or why the plan cannot be made again."""
    free = model.cover.free
    views = model.robots
    if free is None:
        return "no world state in the record"
    if sorted(views) != list(range(len(views))) or any(v.start is None for v in views.values()):
        return "not every robot's start is in the record"
    starts = [s for r in range(len(views)) if (s := views[r].start) is not None]
    seed = views[0].seed
    try:
        area = work_area(OccupancyGrid(free), starts)
        tree = build_tree(area.cells, views[0].tree_kind or "dfs", seed=seed,
                          starts=[cell_of(s) for s in starts])
        plan = algorithm(algo).load_plan()(area, tree, algo, seed)
    except PlannerError as error:
        return f"the plan cannot be made again: {error}"
    return {rp.robot: rp.walk_out for rp in plan.robots}


def walk_out_redundancy(model: FleetModel, algo: str) -> tuple[str, str]:
    """(status, detail) of the promise: "ok", "failed" or "skipped" and why."""
    if not any(v.path for v in model.robots.values()):
        return "skipped", "no ground-truth walks in the record"
    walk_outs = walk_out_moves(model, algo)
    if isinstance(walk_outs, str):
        return "skipped", walk_outs
    entries: Counter[SubCell] = Counter()
    for robot, view in model.robots.items():
        entries.update(view.path[walk_outs.get(robot, 0):])  # path[w] is where the region starts
    twice = sorted(c for c, n in entries.items() if n > 1)
    crossed = sum(walk_outs.values())
    if twice:
        return "failed", (f"{len(twice)} sub-cells entered more than once off the walk-outs, "
                          f"e.g. {twice[:5]}")
    return "ok", f"every sub-cell once besides {crossed} walk-out moves"
