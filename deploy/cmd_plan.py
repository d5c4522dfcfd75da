"""``mstc plan``: load a map, build a tree, allocate the cycle, print or plot the plan."""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any

from bus import argtypes
from bus.argtypes import positive_int
from deploy.errors import UsageError
from planner.algorithms import algorithm, choices_help, names
from planner.geometry import cell_of
from planner.grid import work_area
from planner.maps import resolve_world
from planner.metrics import PlanMetrics, plan_metrics
from planner.offline.plan import make_plan
from planner.placement import parse_starts, random_starts
from planner.trees import ALL_TREE_KINDS, build_tree
from planner.types import Plan

ALGOS = names(plans=True)  # every algorithm that makes an offline plan


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--world", "--map", dest="world", required=True, metavar="FILE|NAME",
                        help="map file (.txt, .map, .yaml, .pgm, .png) or a builtin world "
                             "name (--map: the same option, its older spelling)")
    parser.add_argument("--cell-size", type=positive_int, default=None, metavar="PX",
                        help="pixels per sub-cell (tool width) for image maps")
    robots = parser.add_mutually_exclusive_group(required=True)
    robots.add_argument("--starts", metavar="R,C;R,C;...",
                        help="robot starts as sub-cell coordinates (row, col)")
    robots.add_argument("-n", "--robots", metavar="K",
                        help="place K robots at random free sub-cells (see --seed). "
                             "Deprecated: --robots 'R,C;R,C;...' (start positions), the old "
                             "meaning, still works; use --starts")
    robots.add_argument("--random-robots", type=positive_int, metavar="K",
                        help="the same as --robots K (an alias kept for old scripts)")
    parser.add_argument("--seed", type=argtypes.seed, default=0,
                        help="seed for placement and trees")
    parser.add_argument("--algo", choices=ALGOS, default="opt",
                        help=f"{choices_help(ALGOS)} (balanced: one STC walk per region, "
                             f"--tree does not apply; default opt)")
    parser.add_argument("--tree", choices=ALL_TREE_KINDS, default="dfs",
                        help="spanning tree kind (createtree: paper 000; tmstc: paper 002)")
    parser.add_argument("--speeds", metavar="S,S,...",
                        help="per-robot speeds (opt only), sub-cells per time unit")
    parser.add_argument("--fuel", metavar="F,F,...",
                        help="per-robot fuel limits in moves (opt only; '-' for unlimited)")
    parser.add_argument("--json", action="store_true", help="print the plan as JSON")
    parser.add_argument("--plot", metavar="OUT.png", help="draw map, tree and paths")


def _floats(text: str | None, k: int, what: str) -> list[float] | None:
    if text is None:
        return None
    try:
        values = [float(v) for v in text.split(",")]
    except ValueError as error:
        raise UsageError(f"--{what}: expected {k} comma-separated numbers ({error})") from None
    if len(values) != k or any(v <= 0 for v in values):
        raise UsageError(f"--{what}: expected {k} positive numbers, got {text!r}")
    return values


def _fuel(text: str | None, k: int) -> list[int | None] | None:
    if text is None:
        return None
    items = text.split(",")
    if len(items) != k:
        raise UsageError(f"--fuel: expected {k} values, got {len(items)}")
    try:
        return [None if v.strip() in ("-", "") else int(v) for v in items]
    except ValueError:
        raise UsageError(f"--fuel: expected integers or '-', got {text!r}") from None


def plan_to_json(plan: Plan, metrics: PlanMetrics) -> dict[str, Any]:
    """The stable JSON shape other tools read (coordinates are sub-cells, row then col)."""
    return {
        "n": plan.n,
        "k": plan.k,
        "algo": plan.algo,
        "makespan": plan.makespan,
        "makespan_time": plan.makespan_time,
        "lower_bound": metrics.lower_bound,
        "robots": [
            {"start": list(r.start), "steps": r.steps, "speed": r.speed,
             "turns": metrics.turns[r.robot],
             "path": [list(p) for p in r.path]}
            for r in plan.robots
        ],
    }


def summary_lines(plan: Plan, metrics: PlanMetrics, tree: str) -> list[str]:
    lines = [
        f"map cells: n = {plan.n} sub-cells, k = {plan.k} robots, tree = {tree}, "
        f"algo = {plan.algo}",
        f"makespan: {plan.makespan} moves (lower bound {metrics.lower_bound}, "
        f"{plan.makespan / max(metrics.lower_bound, 1):.2f}x)",
    ]
    if any(r.speed != 1.0 for r in plan.robots):
        lines.append(f"makespan time: {plan.makespan_time:.2f} (moves / speed)")
    lines.append("robot  start        steps  turns  speed")
    for r in plan.robots:
        lines.append(f"{r.robot:5d}  {r.start!s:11s} {r.steps:6d} "
                     f"{metrics.turns[r.robot]:6d}  {r.speed:5.2f}")
    return lines


def _placement(args: argparse.Namespace) -> tuple[str | None, int | None]:
    """(start positions, robot count): one of them, from --starts, --robots or its aliases."""
    if args.starts is not None:
        return args.starts, None
    if args.random_robots is not None:
        return None, int(args.random_robots)
    text = str(args.robots).strip()
    if text.isascii() and text.isdigit():
        if int(text) < 1:
            raise UsageError(f"--robots: expected at least 1 robot, got {text}")
        return None, int(text)
    print("mstc plan: warning: --robots with start positions is deprecated, use --starts",
          file=sys.stderr)
    return text, None


def run(args: argparse.Namespace) -> int:
    plot = None
    if args.plot:
        from deploy.figure_path import figure_path

        plot = figure_path(args.plot, "--plot")
    grid = resolve_world(args.world, cell_size=args.cell_size)
    starts_text, count = _placement(args)
    if starts_text is not None:
        starts = parse_starts(starts_text)
    else:
        assert count is not None
        starts = random_starts(grid, count, args.seed)
    k = len(starts)
    speeds = _floats(args.speeds, k, "speeds")
    fuel = _fuel(args.fuel, k)
    if (speeds or fuel) and args.algo != "opt":
        raise UsageError("--speeds and --fuel need --algo opt (paper 003, section 4.3)")
    area = work_area(grid, starts)
    tree = build_tree(area.cells, args.tree, seed=args.seed,
                      starts=[cell_of(s) for s in starts])
    if args.algo == "balanced":
        from deploy.settings import LARGE_MAP_SUB_CELLS  # here: 0.1 s of imports, balanced only

        if area.n >= LARGE_MAP_SUB_CELLS:
            # a minute at worst (few robots on a large map: docs/balanced.md, "Follow-up 4"),
            # said on stderr so that --json output stays one document
            print(f"planning balanced for {k} robots on {area.n} sub-cells...",
                  file=sys.stderr, flush=True)
        # the registry's planner, as the agents plan: balanced regions, or opt on the tree
        # when that is better (scipy.optimize is imported only when asked for)
        plan = algorithm("balanced").load_plan()(area, tree, "balanced", args.seed)
    else:
        plan = make_plan(area, tree, args.algo, speeds=speeds, fuel=fuel)
    metrics = plan_metrics(plan)
    if args.json:
        json.dump(plan_to_json(plan, metrics), sys.stdout)
        sys.stdout.write("\n")
    else:
        balanced_regions = args.algo == "balanced" and plan.tree is None
        tree_name = "own region per robot" if balanced_regions else args.tree
        print("\n".join(summary_lines(plan, metrics, tree_name)))
        for note in plan.notes:
            print(f"note: {note}")
    if plot is not None:
        from deploy.plot_plan import plot_plan

        plot_plan(plan, area.grid, plot)
        if not args.json:
            print(f"plot written to {plot}")
    return 0
