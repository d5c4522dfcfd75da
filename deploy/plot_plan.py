"""Draw a plan: the map, the spanning tree and each robot's path in its own colour."""

from __future__ import annotations

from pathlib import Path

from deploy.errors import UsageError
from deploy.figure_path import save_figure
from deploy.monitor.figures import robot_hex
from planner.types import OccupancyGrid, Plan


def plot_plan(plan: Plan, grid: OccupancyGrid, out: Path) -> None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise UsageError(
            "--plot needs matplotlib: pip install 'mstc-swarm[plot]'") from None
    h, w = grid.shape
    fig, ax = plt.subplots(figsize=(max(4.0, w / 6), max(3.0, h / 6)))
    ax.imshow(~grid.free, cmap="Greys", vmin=0, vmax=1.6, interpolation="nearest")
    if plan.tree is not None:
        for (r1, c1), (r2, c2) in plan.tree.edges():
            ax.plot([2 * c1 + 0.5, 2 * c2 + 0.5], [2 * r1 + 0.5, 2 * r2 + 0.5],
                    color="0.55", linewidth=1.0, zorder=1)
    for robot in plan.robots:
        colour = robot_hex(robot.robot)
        rows = [p[0] for p in robot.path]
        cols = [p[1] for p in robot.path]
        ax.plot(cols, rows, color=colour, linewidth=1.6, zorder=2,
                label=f"robot {robot.robot}: {robot.steps} moves")
        ax.scatter([robot.start[1]], [robot.start[0]], color=colour, edgecolor="black",
                   s=60, zorder=3)
    ax.set_title(f"{plan.algo}: n = {plan.n}, k = {plan.k}, makespan = {plan.makespan}")
    ax.set_xticks([])
    ax.set_yticks([])
    if plan.k <= 12:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize="small")
    fig.tight_layout()
    save_figure(fig, out, "--plot", dpi=110)
    plt.close(fig)
