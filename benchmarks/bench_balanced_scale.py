"""Balanced planning at scale (issue 14, item 4): time, memory and makespan against k and map size.

    .venv/bin/python benchmarks/bench_balanced_scale.py                  # the docs' table
    .venv/bin/python benchmarks/bench_balanced_scale.py --ks 50,300 --sizes 256 --seeds 1
    .venv/bin/python benchmarks/bench_balanced_scale.py --no-memory      # times without tracing

Instances are fresh from the seed: a city map (planner.maps.city.city_grid: streets, blocks,
yards, parks; 256 x 256 sub-cells hold about 47 000 free ones) and k robots at random
sub-cells (planner.placement.random_starts). Each instance is planned by the registry's
balanced planner (planner.balanced.plan.plan_for: the regions, or opt on the same tree when
that is better) and by opt (planner.offline.plan.make_plan on the tree `mstc plan` builds
by default, dfs), in the same run. Columns: CPU seconds of one call (process_time; the
shared machine's load shows in wall time only), peak traced memory of the call
(tracemalloc: Python and numpy allocations; tracing slows Python code down, so times come
from a second, untraced call unless --no-memory), the makespan, moves over the lower bound
ceil(n/k) - 1 in %, and the balanced makespan over opt's. Every plan is checked
(planner.invariants.check_plan, relaxed for walk-outs as its notes promise).
"""

from __future__ import annotations

import argparse
import functools
import math
import time
import tracemalloc
from collections.abc import Callable

from planner.balanced.plan import FALLBACK, OPT_KEPT, WALK_OUT, plan_for
from planner.grid import WorkArea, work_area
from planner.invariants import check_plan
from planner.maps.city import city_grid
from planner.offline.plan import make_plan
from planner.placement import random_starts
from planner.trees import build_tree
from planner.types import Plan


def instance(size: int, k: int, seed: int) -> WorkArea:
    grid = city_grid(size, seed)
    return work_area(grid, random_starts(grid, k, seed))


def check(plan: Plan, area: WorkArea) -> None:
    if any(note.startswith(WALK_OUT) for note in plan.notes):
        check_plan(plan, area, max_visits=plan.k + 1, own_revisits_only=False)
    elif any(note.startswith((FALLBACK, OPT_KEPT)) for note in plan.notes):
        check_plan(plan, area, max_visits=2)
    else:
        check_plan(plan, area)


def run(make: Callable[[], Plan], memory: bool) -> tuple[Plan, float, float]:
    """The plan, CPU seconds of an untraced call and peak traced MiB (nan: not traced)."""
    peak = math.nan
    if memory:
        tracemalloc.start()
        make()
        peak = tracemalloc.get_traced_memory()[1] / 2 ** 20
        tracemalloc.stop()
    cpu = time.process_time()
    plan = make()
    return plan, time.process_time() - cpu, peak


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ks", default="50,75,100,300,1000")
    parser.add_argument("--sizes", default="256", help="city map sizes in sub-cells")
    parser.add_argument("--size-ks", default="100",
                        help="k for the extra map sizes (sizes other than 256)")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--no-memory", action="store_true")
    args = parser.parse_args()
    cases = [(256, k) for k in map(int, args.ks.split(","))] if "256" in args.sizes.split(",") \
        else []
    cases += [(int(s), k) for s in args.sizes.split(",") if int(s) != 256
              for k in map(int, args.size_ks.split(","))]
    print("| map | n | k | seed | LB | balanced | % over LB | vs opt | kept | "
          "CPU s | peak MiB | opt | opt CPU s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    for size, k in cases:
        for seed in range(args.seeds):
            area = instance(size, k, seed)
            tree = build_tree(area.cells, "dfs", seed=seed)
            bound = math.ceil(area.n / k) - 1
            plan, cpu, peak = run(functools.partial(plan_for, area, tree, "balanced", seed),
                                  not args.no_memory)
            check(plan, area)
            opt, opt_cpu, _ = run(functools.partial(make_plan, area, tree, "opt"), False)
            kept = "opt" if any(n.startswith(OPT_KEPT) for n in plan.notes) else (
                "walks" if any(n.startswith(WALK_OUT) for n in plan.notes) else "regions")
            over = 100.0 * (plan.makespan - bound) / bound
            print(f"| city {size} | {area.n} | {k} | {seed} | {bound} | {plan.makespan} | "
                  f"{over:.1f} | {plan.makespan / opt.makespan:.2f} | {kept} | {cpu:.2f} | "
                  f"{peak:.0f} | {opt.makespan} | {opt_cpu:.2f} |", flush=True)


if __name__ == "__main__":
    main()
