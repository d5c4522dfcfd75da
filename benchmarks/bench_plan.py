"""Benchmark: the whole `mstc plan` pipeline on the 30 x 20 grid (paper 003's 2400 sub-cells).

Prints the median in-process time of load -> work-area -> tree -> cycle -> allocation ->
metrics for each algorithm and tree kind (target: <= 100 ms beyond interpreter start-up), and
the wall time of the `mstc plan` command against a bare `python -c pass` measured side by side.

    .venv/bin/python benchmarks/bench_plan.py [--repeats 21]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

from planner.grid import work_area
from planner.maps import resolve_world
from planner.metrics import plan_metrics
from planner.offline.plan import make_plan
from planner.placement import random_starts
from planner.trees import build_tree


def pipeline(algo: str, tree_kind: str, k: int, seed: int) -> int:
    grid = resolve_world("grid30x20")
    starts = random_starts(grid, k, seed)
    area = work_area(grid, starts)
    tree = build_tree(area.cells, tree_kind, seed=seed)
    plan = make_plan(area, tree, algo)
    return plan_metrics(plan).makespan


def median_ms(fn: object, repeats: int) -> float:
    times = []
    for i in range(repeats):
        started = time.perf_counter()
        fn(i)  # type: ignore[operator]
        times.append(time.perf_counter() - started)
    return 1000 * statistics.median(times)


def command_ms(argv: list[str], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        started = time.perf_counter()
        subprocess.run(argv, check=True, stdout=subprocess.DEVNULL)
        times.append(time.perf_counter() - started)
    return 1000 * statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--repeats", type=int, default=21)
    parser.add_argument("--robots", type=int, default=30)
    args = parser.parse_args()
    print(f"in-process pipeline, grid30x20 (2400 sub-cells), k = {args.robots}, "
          f"median of {args.repeats}")
    for tree_kind in ("dfs", "random", "kruskal"):
        for algo in ("nb", "bt", "opt"):
            ms = median_ms(lambda i, a=algo, t=tree_kind: pipeline(a, t, args.robots, i),
                           args.repeats)
            print(f"  tree {tree_kind:8s} algo {algo:3s}: {ms:7.2f} ms")
    bare = command_ms([sys.executable, "-c", "pass"], 7)
    imports = command_ms([sys.executable, "-c", "import numpy, scipy.sparse.csgraph"], 7)
    mstc = command_ms([sys.executable, "-m", "deploy.cli", "plan", "--map", "grid30x20",
                       "--random-robots", str(args.robots), "--algo", "opt"], 7)
    print(f"command wall time (median of 7): python -c pass {bare:.0f} ms, "
          f"python + numpy/scipy imports {imports:.0f} ms, mstc plan {mstc:.0f} ms "
          f"-> {mstc - bare:.0f} ms beyond interpreter start-up")


if __name__ == "__main__":
    main()
