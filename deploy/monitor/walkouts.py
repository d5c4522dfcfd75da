"""The balanced planner's revisit promise checked on a record: every sub-cell is entered once
except by moves that only lead a robot to its region (its walk-out) and the traffic detours
the robots state (steps aside and back where walks cross).

How long each robot's walk-out is comes from the plan itself, made again from what the record
holds (the world, each robot's start, the seed and tree kind its agent announced): the
planner is pure and deterministic, and the agents compared digests of that very plan. The
record holds those digests too: a plan made again that does not match them (a record made
by another version of the planner) is not used, and the check is skipped with that reason. Where
the registry's planner kept plain optimal MSTC instead (its makespan was smaller: a note
starting with ``planner.balanced.plan.OPT_KEPT``), the robots walked opt's plan and opt's
promise holds instead (``kept_opt``).
"""

from __future__ import annotations

from collections import Counter

from deploy.monitor.model import FleetModel
from planner.algorithms import algorithm
from planner.digest import plan_digest
from planner.errors import PlannerError
from planner.geometry import cell_of
from planner.grid import work_area
from planner.trees import build_tree
from planner.types import OccupancyGrid, Plan, SubCell


def remade_plan(model: FleetModel, algo: str) -> Plan | str:
    """The plan the agents computed, made again from the record, or why it cannot be."""
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
        plan: Plan = algorithm(algo).load_plan()(area, tree, algo, seed)
    except PlannerError as error:
        return f"the plan cannot be made again: {error}"
    announced = {v.plan_digest for v in views.values() if v.plan_digest}
    made = plan_digest(plan)
    if announced and announced != {made}:
        # recorded with another planner (an older version): judging the walks by this
        # plan's walk-outs, or by whether it kept opt, would be judging another plan
        return (f"the plan made again ({made[:12]}) is not the one the robots announced "
                f"({', '.join(sorted(d[:12] for d in announced))}): recorded with another "
                "planner version")
    return plan


def kept_opt(plan: Plan) -> bool:
    """True if the registry's balanced planner kept optimal MSTC for this plan."""
    from planner.balanced.plan import OPT_KEPT  # the planner is loaded with the plan anyway

    return any(note.startswith(OPT_KEPT) for note in plan.notes)


def walk_out_redundancy(model: FleetModel, plan: Plan) -> tuple[str, str]:
    """(status, detail) of the promise for ``plan`` (the remade one, regions not opt):
    "ok" or "failed" and why (the report skips records without ground-truth walks).

    Walks that cross meet: a robot may step aside and back (planner.offline.traffic), and
    each such move enters one sub-cell off its plan. The robots state how many they made
    when they complete ("N detours"), so the promise allows that many entries more."""
    walk_outs = {rp.robot: rp.walk_out for rp in plan.robots}
    entries: Counter[SubCell] = Counter()
    for robot, view in model.robots.items():
        entries.update(view.path[walk_outs.get(robot, 0):])  # path[w] is where the region starts
    twice = sorted(c for c, n in entries.items() if n > 1)
    extra = sum(n - 1 for n in entries.values() if n > 1)
    detours = sum(v.traffic.detours for v in model.robots.values() if v.traffic is not None)
    crossed = sum(walk_outs.values())
    if extra > detours:
        return "failed", (f"{len(twice)} sub-cells entered more than once off the walk-outs "
                          f"({extra} entries too many, the robots stated {detours} traffic "
                          f"detours), e.g. {twice[:5]}")
    if twice:
        return "ok", (f"every sub-cell once besides {crossed} walk-out moves and {extra} "
                      f"entries on the {detours} traffic detours the robots stated")
    return "ok", f"every sub-cell once besides {crossed} walk-out moves"
