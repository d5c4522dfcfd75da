"""Draw one re-plan after a death: where the survivors stand and what is left, the re-plan
without the regrown regions, with them, and refined (docs/balanced.md).

    .venv/bin/python benchmarks/plot_replan.py docs/img/replan_regrown.png
    .venv/bin/python benchmarks/plot_replan.py out.png --seed 1 --dead 0 --coverage 0.3

The fleet is the office world with 6 robots at seeded random starts and the balanced plan;
robot ``--dead`` dies when every robot has walked ``--coverage`` of the plan's makespan.
The state at the death is read off the plan (every robot at the same step of its path);
the re-plans are planner.offline.rebalance's: without the regrown regions
(``REGROW_MAX_SUB_CELLS = 0``) and with them, both unrefined (``REFINE_MAX_SUB_CELLS = 0``),
and the re-plan as it is (refined by planner.offline.refine). A lighter sub-cell is
covered; each survivor's route in its colour from where it stands (a dot); the dead
robot's orphans are black.
"""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING

import numpy as np

from deploy.figure_path import figure_path, save_figure
from deploy.monitor.figures import robot_hex
from planner.algorithms import algorithm
from planner.geometry import cell_of
from planner.grid import work_area
from planner.maps import resolve_world
from planner.offline import rebalance as rebalance_module
from planner.offline.rebalance import Replan, frozen_at, orphans, plan_order, rebalance
from planner.placement import random_starts
from planner.trees import build_tree
from planner.types import BoolArray, Cycle, OccupancyGrid, Plan

if TYPE_CHECKING:
    from matplotlib.axes import Axes


def office_plan(seed: int) -> tuple[OccupancyGrid, Plan]:
    grid = resolve_world("office")
    area = work_area(grid, random_starts(grid, 6, seed))
    tree = build_tree(area.cells, "dfs", seed=seed, starts=[cell_of(s) for s in area.starts])
    plan: Plan = algorithm("balanced").load_plan()(area, tree, "balanced", seed)
    return grid, plan


def draw(ax: Axes, grid: OccupancyGrid, cycle: Cycle, covered: BoolArray,
         routes: dict[int, tuple[int, ...]], start: dict[int, int], black: list[int],
         title: str) -> None:
    shade = np.where(grid.free, 0.0, 1.0)
    for index in np.flatnonzero(covered):
        r, c = cycle.at(int(index))
        shade[r, c] = 0.25
    ax.imshow(shade, cmap="Greys", vmin=0, vmax=1.6, interpolation="nearest")
    for robot, route in routes.items():
        points = [cycle.at(i) for i in (start[robot], *route)]
        colour = robot_hex(robot)
        ax.plot([p[1] for p in points], [p[0] for p in points], color=colour,
                linewidth=1.4, label=f"robot {robot}: {len(route)} moves")
        ax.scatter([points[0][1]], [points[0][0]], color=colour, edgecolor="black", s=50,
                   zorder=3)
    if black:
        spots = [cycle.at(i) for i in black]
        ax.scatter([p[1] for p in spots], [p[0] for p in spots], color="black", s=6,
                   zorder=2, label="orphans")
    ax.set_title(title, fontsize="small")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.legend(loc="upper left", bbox_to_anchor=(0.0, -0.02), fontsize="x-small", ncol=2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("out", help="the figure to write (.png unless another suffix)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--dead", type=int, default=5, help="the robot that dies (5)")
    parser.add_argument("--coverage", type=float, default=0.3,
                        help="share of the makespan walked when it dies (0.3)")
    args = parser.parse_args()
    out = figure_path(args.out, "out")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    grid, plan = office_plan(args.seed)
    step = int(args.coverage * plan.makespan)
    covered, survivors = frozen_at(plan, {rp.robot: step for rp in plan.robots}, {args.dead})
    rank = plan_order(plan)
    refined = rebalance(plan.cycle, covered, survivors, rank)
    rebalance_module.REFINE_MAX_SUB_CELLS = 0
    with_regions = rebalance(plan.cycle, covered, survivors, rank)
    rebalance_module.REGROW_MAX_SUB_CELLS = 0
    without: Replan = rebalance(plan.cycle, covered, survivors, rank)
    start = {s.robot: s.position for s in survivors}
    fig, axes = plt.subplots(1, 4, figsize=(20, 5.2))
    draw(axes[0], grid, plan.cycle, covered, {s.robot: s.route for s in survivors}, start,
         orphans(covered, survivors, rank),
         f"robot {args.dead} dead at move {step} of {plan.makespan}: routes left")
    draw(axes[1], grid, plan.cycle, covered, without.routes, start, [],
         f"re-plan without regrown regions: {step} + {without.makespan} moves")
    draw(axes[2], grid, plan.cycle, covered, with_regions.routes, start, [],
         f"re-plan with them: {step} + {with_regions.makespan} moves")
    draw(axes[3], grid, plan.cycle, covered, refined.routes, start, [],
         f"refined (the re-plan now): {step} + {refined.makespan} moves")
    fig.tight_layout()
    save_figure(fig, out, "out", dpi=90)
    plt.close(fig)
    print(f"wrote {out}: re-plan {without.makespan} -> {with_regions.makespan} -> "
          f"{refined.makespan} moves after move {step} (fault-free {plan.makespan})")


if __name__ == "__main__":
    main()
