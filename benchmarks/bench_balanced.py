"""Balanced planner vs. the lower bound (issue 7), with opt-MSTC on a random tree for contrast.

    .venv/bin/python benchmarks/bench_balanced.py                 # the issue's table
    .venv/bin/python benchmarks/bench_balanced.py --seeds 3 --ks 10,30
    .venv/bin/python benchmarks/bench_balanced.py --failures 5    # plus takeover replays
    .venv/bin/python benchmarks/bench_balanced.py --plot docs/img/balanced_regions.png
    .venv/bin/python benchmarks/bench_balanced.py --obstacles 80 --ks 20,30 --per-instance
    .venv/bin/python benchmarks/bench_balanced.py --obstacles 80 --ks 30 --repeat 3

Instances are generated from the seed: a rows x cols coarse grid (default 20 x 30, 2400
sub-cells), with --obstacles random blocked cells, and k robots at distinct random sub-cells
of the largest free component (planner.placement.random_starts). The work-area is that
component, so the lower bound ceil(n/k) - 1 uses its n. Times are wall-clock (perf_counter)
and CPU (process_time) seconds of one call; the machine's load shows in the first only.
With --repeat N each plan is made N times and the fastest times are kept: on a machine
shared with other jobs even CPU time varies by 20-50 % from run to run.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from planner.balanced import balanced_plan
from planner.balanced.plan import FALLBACK, WALK_OUT
from planner.balanced.takeover import simulate_failures
from planner.grid import WorkArea, expand, work_area
from planner.invariants import check_plan
from planner.offline.plan import make_plan
from planner.placement import random_starts
from planner.trees import build_tree
from planner.types import OccupancyGrid, Plan


def instance(rows: int, cols: int, obstacles: int, k: int, seed: int) -> WorkArea:
    rng = np.random.default_rng(seed)
    coarse = np.ones((rows, cols), dtype=bool)
    coarse.ravel()[rng.choice(rows * cols, size=obstacles, replace=False)] = False
    grid = OccupancyGrid(expand(coarse), name=f"random-{rows}x{cols}-{obstacles}-{seed}")
    return work_area(grid, random_starts(grid, k, seed))


def opt_mstc(area: WorkArea, seed: int) -> Plan:
    return make_plan(area, build_tree(area.cells, "random", seed=seed), "opt")


def check(plan: Plan, area: WorkArea) -> None:
    """Strict for plain balanced plans (each sub-cell once, by one robot); else as promised."""
    if any(note.startswith(WALK_OUT) for note in plan.notes):
        check_plan(plan, area, max_visits=plan.k + 1, own_revisits_only=False)
    elif plan.algo == "balanced" and not any(note.startswith(FALLBACK) for note in plan.notes):
        check_plan(plan, area)
    else:
        check_plan(plan, area, max_visits=2)


@dataclass
class Row:
    bounds: list[int]
    makespans: list[int]
    wall: list[float]
    cpu: list[float]

    def line(self, name: str) -> str:
        over = [100.0 * (m - b) / b for m, b in zip(self.makespans, self.bounds, strict=True)]
        extra = [m - b for m, b in zip(self.makespans, self.bounds, strict=True)]
        return (f"| {name} | {statistics.mean(self.bounds):.1f} | "
                f"{statistics.mean(self.makespans):.1f} | {max(self.makespans)} | "
                f"{statistics.mean(over):.2f} | {max(over):.2f} | {max(extra)} | "
                f"{statistics.median(self.wall):.3f} | {max(self.wall):.3f} | "
                f"{statistics.median(self.cpu):.3f} | {max(self.cpu):.3f} |")


def measure(planner: Callable[[WorkArea, int], Plan], areas: list[tuple[WorkArea, int]],
            repeat: int = 1) -> tuple[Row, list[Plan]]:
    row = Row([], [], [], [])
    plans = []
    for area, seed in areas:
        walls, cpus = [], []
        for _ in range(repeat):
            wall, cpu = time.perf_counter(), time.process_time()
            plan = planner(area, seed)
            walls.append(time.perf_counter() - wall)
            cpus.append(time.process_time() - cpu)
        row.wall.append(min(walls))
        row.cpu.append(min(cpus))
        check(plan, area)
        row.bounds.append(math.ceil(area.n / len(area.starts)) - 1)
        row.makespans.append(plan.makespan)
        plans.append(plan)
    return row, plans


def takeover_line(plans: list[Plan], failures: int, seed: int) -> str:
    """Coverage time when ``failures`` robots die at random times, over the instances."""
    rng = np.random.default_rng(seed)
    ratios = []
    for plan in plans:
        dead = rng.choice(plan.k, size=min(failures, plan.k - 1), replace=False)
        when = {int(r): int(rng.integers(0, plan.makespan + 1)) for r in dead}
        result = simulate_failures(plan, when, recovery="takeover")
        assert result.complete, "takeover left sub-cells uncovered"
        assert result.coverage_time is not None
        ratios.append(result.coverage_time / max(1, plan.makespan))
    return (f"takeover, {failures} random failures: coverage time / plan makespan mean "
            f"{statistics.mean(ratios):.2f}, max {max(ratios):.2f} (all complete)")


def plot(out: str, rows: int, cols: int) -> None:
    """Regions and walks of two instances (80 obstacles; k = 10 seed 0 and k = 30 seed 5)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4))
    for ax, (k, seed) in zip(axes, ((10, 0), (30, 5)), strict=True):
        area = instance(rows, cols, 80, k, seed)
        plan = balanced_plan(area, seed=seed)
        owner = np.full(area.grid.shape, np.nan)
        for rp in plan.robots:
            for r, c in rp.path:
                owner[r, c] = (rp.robot * 7) % k
        ax.imshow(owner, cmap="tab20", interpolation="nearest")
        ax.imshow(np.where(area.sub_cells, np.nan, 0.0), cmap="gray", interpolation="nearest")
        for rp in plan.robots:
            path = np.asarray(rp.path)
            ax.plot(path[:, 1], path[:, 0], color="black", linewidth=0.4)
            ax.plot(rp.start[1], rp.start[0], "o", color="white", markersize=2.5,
                    markeredgecolor="black", markeredgewidth=0.5)
        bound = math.ceil(area.n / k) - 1
        ax.set_title(f"k = {k}, seed {seed}: makespan {plan.makespan}, LB {bound}", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    print(f"wrote {out}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", type=int, default=20)
    parser.add_argument("--cols", type=int, default=30)
    parser.add_argument("--obstacles", default="0,80")
    parser.add_argument("--ks", default="3,5,10,20,30")
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--no-contrast", action="store_true", help="skip opt-MSTC")
    parser.add_argument("--failures", type=int, default=0,
                        help="also replay the balanced plans with this many failures")
    parser.add_argument("--plot", metavar="OUT.png", help="draw two instances and stop")
    parser.add_argument("--per-instance", action="store_true",
                        help="also list the balanced planner's moves over LB per seed")
    parser.add_argument("--repeat", type=int, default=1,
                        help="make each plan this many times and keep the fastest times")
    args = parser.parse_args()
    if args.plot:
        plot(args.plot, args.rows, args.cols)
        return
    print("| planner | LB mean | makespan mean | makespan max | % over LB mean | "
          "% over LB max | max moves over LB | wall s median | wall s max | "
          "CPU s median | CPU s max |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    notes = []
    for obstacles in (int(x) for x in args.obstacles.split(",")):
        for k in (int(x) for x in args.ks.split(",")):
            areas = [(instance(args.rows, args.cols, obstacles, k, seed), seed)
                     for seed in range(args.seeds)]
            tag = f"obstacles {obstacles}, k {k}"
            row, plans = measure(lambda a, s: balanced_plan(a, seed=s), areas, args.repeat)
            print(row.line(f"balanced ({tag})"), flush=True)
            if args.per_instance:
                extra = [m - b for m, b in zip(row.makespans, row.bounds, strict=True)]
                notes.append(f"{tag}: moves over LB by seed: {' '.join(map(str, extra))}")
            if not args.no_contrast:
                contrast = measure(opt_mstc, areas, args.repeat)[0]
                print(contrast.line(f"opt-MSTC random tree ({tag})"), flush=True)
            if args.failures:
                notes.append(f"{tag}: {takeover_line(plans, args.failures, k)}")
    for note in notes:
        print(note)


if __name__ == "__main__":
    main()
