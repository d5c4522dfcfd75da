"""balanced_plan: balanced connected regions, one STC walk per robot inside its own region."""

from __future__ import annotations

import math

from planner.balanced.coverage import region_path
from planner.balanced.cyclesplit import split_cycle
from planner.balanced.regions import plan_regions
from planner.cycle import stc_cycle
from planner.grid import WorkArea
from planner.offline.plan import make_plan
from planner.trees import build_tree
from planner.types import Cycle, Plan, RobotPlan, SpanningTree

ALGO = "balanced"
WALK_OUT = "balanced walk-out"  # note prefix of plans in which some sub-cells are revisited
FALLBACK = "balanced fallback"  # note prefix of plans that are optimal MSTC instead
OPT_KEPT = "balanced kept opt"  # note prefix of plans where plain opt on the tree was better
SPLIT = "balanced cycle split"  # note prefix of plans that split the tree's cycle instead


def plan_for(area: WorkArea, tree: SpanningTree, algo: str, seed: int = 0) -> Plan:
    """The registry's entry point (planner.algorithms): the best of three plans. The
    balanced regions; plain opt on ``tree`` (what ``--algo opt`` plans on the same instance),
    so ``--algo balanced`` is never worse than ``--algo opt``; and a split of that tree's
    cycle into stretches any robot may walk to (``cyclesplit``). Ties keep the earlier."""
    del algo
    opt = make_plan(area, tree, "opt")  # its cycle is the tree's, the split's too
    return better_split(_shorter_of(balanced_plan(area, seed=seed), opt, tree), area, opt.cycle,
                        tree)


def better_than_opt(plan: Plan, area: WorkArea, tree: SpanningTree) -> Plan:
    """``plan``, or optimal MSTC on ``tree`` (noted OPT_KEPT) when that finishes sooner."""
    return _shorter_of(plan, make_plan(area, tree, "opt"), tree)


def _shorter_of(plan: Plan, opt: Plan, tree: SpanningTree) -> Plan:
    if opt.makespan >= plan.makespan:
        return plan
    note = (f"{OPT_KEPT}: optimal MSTC on the given tree plans {opt.makespan} moves, the "
            f"balanced regions {plan.makespan}")
    return Plan(algo=ALGO, cycle=opt.cycle, robots=opt.robots, tree=tree,
                notes=(note, *opt.notes))


def better_split(plan: Plan, area: WorkArea, cycle: Cycle, tree: SpanningTree) -> Plan:
    """``plan``, or a split of ``cycle`` (``tree``'s, noted SPLIT and WALK_OUT) when one
    finishes sooner: every robot walks to one end of a stretch of the cycle and covers it."""
    robots = split_cycle(area, cycle, below=plan.makespan)
    if robots is None:
        return plan
    makespan = max(rp.steps for rp in robots)
    walks = sum(rp.walk_out for rp in robots)
    notes = (f"{SPLIT}: stretches of the given tree's cycle, any robot to any stretch, plan "
             f"{makespan} moves against {plan.makespan} (lower bound "
             f"{math.ceil(area.n / len(area.starts)) - 1})",
             f"{WALK_OUT}: the robots walk to their stretches first ({walks} moves in all), "
             "over sub-cells others cover too")
    return Plan(algo=ALGO, cycle=cycle, robots=robots, tree=tree, notes=notes)


def balanced_plan(area: WorkArea, *, seed: int = 0) -> Plan:
    """A plan whose robots each cover one region of near-equal size, starting where they stand.

    Robot r walks ``size_r - 1`` moves and no sub-cell is visited twice; with the regions as
    balanced as the map allows the makespan is at most the lower bound ceil(n/k) - 1 plus
    one (regions hold an even number of sub-cells). A robot boxed in or squeezed by others'
    starts may first walk to a region elsewhere (a note starting with WALK_OUT says so; the walk
    out crosses sub-cells that other robots cover too). ``plan.cycle`` is an STC cycle of the
    whole area (a Kruskal tree from ``seed``): it gives each robot a ring position
    (``start_index``) for the takeover order; the robots do not walk it, so ``legs`` are
    empty. Never raises for a valid work-area: in the one case the partition cannot cover
    the map (divided start cells walling off cells), the plan is optimal MSTC on that cycle.
    """
    tree = build_tree(area.cells, "kruskal", seed=seed)
    cycle = stc_cycle(tree, start=area.starts[0])
    k = len(area.starts)
    bound = math.ceil(area.n / k) - 1
    parts, routes = plan_regions(area, seed=seed)
    if parts is None:
        fallback = make_plan(area, tree, "opt")
        note = (f"{FALLBACK}: cells shared by several robots' starts wall off part of the map; "
                "fell back to optimal MSTC on the area's cycle")
        return Plan(algo=ALGO, cycle=cycle, robots=fallback.robots, tree=tree,
                    notes=(note, *fallback.notes))
    robots = []
    for region in parts.regions:
        walk_out = routes.get(region.robot, (region.start,))
        start = walk_out[0]
        robots.append(RobotPlan(robot=region.robot, start=start,
                                start_index=cycle.position(start), legs=(),
                                path=walk_out[:-1] + region_path(region, seed=seed),
                                walk_out=len(walk_out) - 1))
    sizes = parts.sizes
    notes = [f"balanced: n = {area.n} sub-cells, k = {k} robots, lower bound ceil(n/k) - 1 = "
             f"{bound} moves; regions of {min(sizes)}..{max(sizes)} sub-cells after "
             f"{parts.transfers} balancing moves"]
    if routes:
        moves = ", ".join(f"robot {r}: {len(w) - 1}" for r, w in sorted(routes.items()))
        notes.append(f"{WALK_OUT}: robots boxed in or squeezed by others' starts walk to "
                     f"their regions first ({moves} moves), over sub-cells others cover too")
    return Plan(algo=ALGO, cycle=cycle, robots=tuple(robots), tree=None, notes=tuple(notes))
