"""Balanced plans against the lower bound and against opt, on generated map families (issue 14).

    .venv/bin/python benchmarks/bench_balanced_families.py                 # the docs' table
    .venv/bin/python benchmarks/bench_balanced_families.py --seeds 5 --first-seed 100
    .venv/bin/python benchmarks/bench_balanced_families.py --families maze,rooms --ks 10,20
    .venv/bin/python benchmarks/bench_balanced_families.py --large --ks 20,50 --seeds 2

Every instance is fresh from its seed: a generated world (planner.maps.generated: open,
30 % and 10 % random obstacles, rooms with doors, mazes, city blocks; the map's seed is the
instance seed) and k robots at random sub-cells of it (planner.placement.random_starts,
the same seed). Small maps (about 40 x 40 cells) carry k = 5-30, large ones (about
120 x 120 cells, 45 000-58 000 sub-cells) k = 100 and 300. Each instance is planned by the
registry's balanced planner (planner.balanced.plan.plan_for: the best of the regions, opt on
the same tree and a split of that tree's cycle) and by opt on the dfs tree `mstc plan` builds
by default, in the same run; every plan is checked (planner.invariants.check_plan, relaxed for walks
as its notes promise). Per family and k: the lower bound ceil(n/k) - 1 (mean), balanced's
moves over it in % (mean and worst instance), balanced / opt (mean and worst), how often
balanced was worse than opt (never, by construction of plan_for: the check that it stays
so), how the plan was made (regions / walks / opt kept / split), and CPU seconds of one call
(process_time, mean and max). On the small maps also the flow bound
(planner.balanced.bounds: it counts the walks every robot must make before it covers
anything alone, and bounds every plan; mazes are far above ceil(n/k) - 1 for that reason)
and balanced's moves over it. Progress goes to stderr, the table to stdout.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from dataclasses import dataclass, field

from bench_balanced_scale import check

from planner.balanced.bounds import flow_bound
from planner.balanced.plan import OPT_KEPT, SPLIT, WALK_OUT, plan_for
from planner.grid import work_area
from planner.maps import resolve_world
from planner.offline.plan import make_plan
from planner.placement import random_starts
from planner.trees import build_tree

SMALL_KS = (5, 10, 20, 30)
LARGE_KS = (100, 300)
# family -> (spec of a small map, spec of a large map), {seed} filled per instance
FAMILIES = {
    "open": ("obstacles:40x40:0:{seed}", "obstacles:120x120:0:{seed}"),
    "obstacles 10 %": ("obstacles:40x40:10%:{seed}", "obstacles:120x120:10%:{seed}"),
    "obstacles 30 %": ("obstacles:40x40:30%:{seed}", "obstacles:120x120:30%:{seed}"),
    "rooms": ("rooms:40x40:{seed}", "rooms:120x120:{seed}"),
    "maze": ("maze:39x39:{seed}", "maze:119x119:{seed}"),
    "city": ("city:40x40:{seed}", "city:120x120:{seed}"),
}


@dataclass
class Row:
    bounds: list[int] = field(default_factory=list)
    over: list[float] = field(default_factory=list)  # % over LB
    flows: list[int] = field(default_factory=list)  # the flow bound (small maps)
    over_flow: list[float] = field(default_factory=list)  # % over it
    vs_opt: list[float] = field(default_factory=list)
    worse: int = 0
    kinds: dict[str, int] = field(default_factory=dict)
    cpu: list[float] = field(default_factory=list)


def measure(spec: str, k: int, seed: int, row: Row, *, flow_too: bool = True) -> str:
    grid = resolve_world(spec)
    area = work_area(grid, random_starts(grid, k, seed))
    tree = build_tree(area.cells, "dfs", seed=seed)
    bound = math.ceil(area.n / k) - 1
    cpu = time.process_time()
    plan = plan_for(area, tree, "balanced", seed)
    row.cpu.append(time.process_time() - cpu)
    check(plan, area)
    opt = make_plan(area, tree, "opt")
    kind = ("opt kept" if any(n.startswith(OPT_KEPT) for n in plan.notes) else
            "split" if any(n.startswith(SPLIT) for n in plan.notes) else
            "walks" if any(n.startswith(WALK_OUT) for n in plan.notes) else "regions")
    row.bounds.append(bound)
    row.over.append(100.0 * (plan.makespan - bound) / bound)
    flow = ""
    if flow_too and k <= max(SMALL_KS):  # k x n arcs: seconds on the small maps only
        lifted = flow_bound(area)
        row.flows.append(lifted)
        row.over_flow.append(100.0 * (plan.makespan - lifted) / lifted)
        flow = f", flow bound {lifted}"
    row.vs_opt.append(plan.makespan / opt.makespan)
    row.worse += plan.makespan > opt.makespan
    row.kinds[kind] = row.kinds.get(kind, 0) + 1
    return f"{spec} k={k}: {plan.makespan} moves, LB {bound}{flow}, opt {opt.makespan} ({kind})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--families", default=",".join(FAMILIES),
                        help="comma-separated (" + ",".join(FAMILIES).replace("%", "%%") + ")")
    parser.add_argument("--ks", default=",".join(map(str, SMALL_KS + LARGE_KS)),
                        help="team sizes; up to 30 on the small maps, above on the large ones")
    parser.add_argument("--seeds", type=int, default=3, help="instances per family and k (3)")
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--large", action="store_true",
                        help="plan every k on the large maps (few robots on a large map: "
                             "regions of hundreds of cells, the planner's slowest case)")
    args = parser.parse_args()
    families = [f.strip() for f in args.families.split(",") if f.strip()]
    for family in families:
        if family not in FAMILIES:
            parser.error(f"--families: unknown {family!r}; choose from {', '.join(FAMILIES)}")
    ks = [int(k) for k in args.ks.split(",")]
    print("| family | k | instances | LB mean | % over LB: mean | worst | flow bound mean | "
          "% over it: mean | worst | balanced / opt: mean | worst | worse than opt | made as | "
          "CPU s: mean | max |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for family in families:
        for k in ks:
            spec = FAMILIES[family][0 if k <= max(SMALL_KS) and not args.large else 1]
            row = Row()
            for seed in range(args.first_seed, args.first_seed + args.seeds):
                print(measure(spec.format(seed=seed), k, seed, row, flow_too=not args.large),
                      file=sys.stderr, flush=True)
            made = ", ".join(f"{kind} {count}" for kind, count in sorted(row.kinds.items()))
            flows = (f"{statistics.mean(row.flows):.1f} | {statistics.mean(row.over_flow):.2f} | "
                     f"{max(row.over_flow):.2f}") if row.flows else "- | - | -"
            print(f"| {family} | {k} | {len(row.over)} | {statistics.mean(row.bounds):.1f} | "
                  f"{statistics.mean(row.over):.2f} | {max(row.over):.2f} | {flows} | "
                  f"{statistics.mean(row.vs_opt):.2f} | {max(row.vs_opt):.2f} | {row.worse} | "
                  f"{made} | {statistics.mean(row.cpu):.2f} | {max(row.cpu):.2f} |",
                  flush=True)


if __name__ == "__main__":
    main()
