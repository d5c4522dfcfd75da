"""The report's picture: the map with each robot's tree edges and walk in its colour, dead
robots marked, and coverage over time. matplotlib is imported only here (optional extra)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from deploy.figure_path import save_figure
from deploy.monitor.figures import robot_hex
from deploy.monitor.model import FleetModel
from deploy.monitor.report import MissionReport


def write_png(model: FleetModel, report: MissionReport, path: Path) -> None:
    """Draw ``model`` (the replayed recording) and the coverage curve into ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_map, ax_curve) = plt.subplots(1, 2, figsize=(11, 5),
                                           gridspec_kw={"width_ratios": [3, 2]})
    _draw_map(ax_map, model)
    _draw_curve(ax_curve, report)
    fig.suptitle(f"mission {report.mission} ({report.algo})")
    fig.tight_layout()
    save_figure(fig, path, "--png", dpi=80)
    plt.close(fig)


def _draw_map(ax: object, model: FleetModel) -> None:
    from matplotlib.axes import Axes

    assert isinstance(ax, Axes)
    if model.cover.free is not None:
        ax.imshow(np.where(model.cover.free, 1.0, 0.35), cmap="gray", vmin=0, vmax=1,
                  origin="upper", interpolation="nearest")
    for (a, b), robot in model.edges.items():
        # Cell (r, c) is sub-cells 2r..2r+1: its centre is at 2r + 0.5.
        ys, xs = [2 * a[0] + 0.5, 2 * b[0] + 0.5], [2 * a[1] + 0.5, 2 * b[1] + 0.5]
        ax.plot(xs, ys, color=robot_hex(robot), linewidth=3, alpha=0.35)
    for robot, view in sorted(model.robots.items()):
        colour = robot_hex(robot)
        if view.path:
            path = np.asarray(view.path)
            ax.plot(path[:, 1], path[:, 0], color=colour, linewidth=1.2, label=f"robot {robot}")
            ax.plot(path[0, 1], path[0, 0], "o", color=colour, markersize=6)
        if view.dead and view.pose is not None:
            ax.plot(view.pose[1], view.pose[0], "x", color="black", markersize=12,
                    markeredgewidth=3)
    ax.set_title("trees (thick), walks (thin), dead robots (x)")
    ax.set_xticks([])
    ax.set_yticks([])
    if model.robots:
        ax.legend(loc="upper left", bbox_to_anchor=(1.0, 1.0), fontsize="small")


def _draw_curve(ax: object, report: MissionReport) -> None:
    from matplotlib.axes import Axes

    assert isinstance(ax, Axes)
    total = report.reachable or max((c for _, _, c in report.curve), default=1)
    sims = [s for _, s, _ in report.curve]
    pct = [100.0 * c / total for _, _, c in report.curve]
    ax.step(sims, pct, where="post")
    for death in report.deaths:
        ax.axvline(_sim_at(report, death.t), color="red", linestyle="--", linewidth=1)
    ax.set_xlabel("simulated seconds")
    ax.set_ylabel("coverage %")
    ax.set_ylim(0, 105)
    ax.set_title("coverage over time (red: deaths)")
    ax.grid(alpha=0.3)


def _sim_at(report: MissionReport, t: float) -> float:
    """The simulated time the curve had reached at receive time ``t``."""
    before = [s for rt, s, _ in report.curve if rt <= t]
    return before[-1] if before else 0.0
