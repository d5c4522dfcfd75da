"""``mstc tree-cover``: connected coverage of a tree by NCOCTA or COCTA (paper 001)."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from deploy.figure_path import save_figure
from planner.algorithms import Family, choices_help, names
from planner.treecover.sim import run_coverage
from planner.treecover.trees import tree_from_spec
from planner.treecover.types import CoverageResult, Tree


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--tree", required=True,
                        help="perfect:N=3,H=7 | general:N=2,H=10,remove=R,at=HEIGHT,seed=S | "
                             "office | FILE.tree (lines 'parent child', # comments)")
    parser.add_argument("-n", "--robots", type=int, required=True, help="team size k")
    parser.add_argument("--algo", choices=names(Family.TREE), default="cocta",
                        help=f"{choices_help(names(Family.TREE))} (default cocta)")
    parser.add_argument("--plot", metavar="PNG", help="save robots' spread over time")
    parser.add_argument("--json", action="store_true", help="print one JSON object")


def run(args: argparse.Namespace) -> int:
    plot = None
    if args.plot:
        from deploy.figure_path import figure_path

        plot = figure_path(args.plot, "--plot")
    tree = tree_from_spec(args.tree)
    result = run_coverage(tree, args.robots, args.algo)
    summary = _summary(tree, result)
    if args.json:
        print(json.dumps(summary))
    else:
        for key, value in summary.items():
            print(f"{key:>22}: {value}")
    if plot is not None:
        _plot(tree, result, plot)
    return 0 if result.connected else 1


def _summary(tree: Tree, result: CoverageResult) -> dict[str, object]:
    return {
        "tree": tree.name, "nodes": tree.n, "height": tree.height,
        "algo": result.algo.value, "robots": result.robots,
        "split_heights": list(result.splits.heights),
        "coverage_time": result.time, "explore_time": result.explore_time,
        "single_robot_time": result.single_time, "speedup": round(result.speedup, 4),
        "connected_every_step": result.connected,
    }


def _plot(tree: Tree, result: CoverageResult, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    steps = np.arange(1, result.time + 1)
    top.plot(steps, result.occupied, lw=0.8)
    top.set_ylabel("occupied nodes")
    order = np.sort(result.visit_time)
    bottom.plot(order, np.arange(1, tree.n + 1), lw=0.8)
    bottom.set_ylabel("nodes visited")
    bottom.set_xlabel("step")
    fig.suptitle(f"{result.algo.value.upper()} on {tree.name}, k={result.robots}, "
                 f"SF={result.speedup:.2f}")
    fig.tight_layout()
    save_figure(fig, path, "--plot", dpi=80)
    plt.close(fig)
