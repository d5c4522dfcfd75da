"""Makespan after deaths, recovery by the papers' takeover vs. re-balancing (issue 14, item 2).

    .venv/bin/python benchmarks/bench_recovery.py                  # the table of docs/balanced.md
    .venv/bin/python benchmarks/bench_recovery.py --seeds 5 --k 6 --coverage 0.3
    .venv/bin/python benchmarks/bench_recovery.py --algos opt,balanced --worlds office
    .venv/bin/python benchmarks/bench_recovery.py --half                # k/2 deaths, random times
    .venv/bin/python benchmarks/bench_recovery.py --replan-scale rooms:120x120:1:100

Lockstep replays (planner.offline.lockstep / planner.balanced.takeover, unit moves, death
known at once). For each instance the fault-free plan is replayed once to find the first
step at which ``--coverage`` of the sub-cells are covered; then each robot in turn dies at
that step and the coverage time with ``--recovery takeover`` and ``rebalance`` is divided by
the fault-free makespan (plan makespan): mean and worst over the robots and instances,
measured side by side on the same deaths. ``ideal`` is the fault-free makespan plus the
dead robot's remaining work shared evenly among the survivors, over the fault-free makespan.

With ``--half``, k/2 robots (seeded choice) die at seeded random steps of the fault-free
makespan instead, and coverage time is divided by the ideal: fault-free makespan plus the
dead robots' remaining moves shared among the survivors.

The takeover is replayed as the papers do (robots as points); the re-balanced runs have
bodies (one per sub-cell, deconflicted by planner.offline.traffic), and ``w/d/b`` is their
waits, detours and bumps summed over the robots of one run, mean over the runs (and the
largest sum of the three in one run).

Instances: the builtin world office with random starts from each seed, and generated
20 x 30 coarse grids (2400 sub-cells) with 0, 60 and 120 random blocked cells (the work-area
is the largest component), random starts; nothing is tuned on a fixed set. ``--worlds``
also takes any world ``mstc up`` does (builtin or generated: ``city:64x64:3``).
"""

from __future__ import annotations

import argparse
import math
import statistics
import time
from collections.abc import Iterator

import numpy as np

from planner.algorithms import algorithm
from planner.geometry import cell_of
from planner.grid import WorkArea, expand, work_area
from planner.maps import resolve_world
from planner.offline.lockstep import TakeoverResult
from planner.placement import random_starts
from planner.trees import build_tree
from planner.types import OccupancyGrid, Plan


def generated(rows: int, cols: int, obstacles: int, k: int, seed: int) -> WorkArea:
    rng = np.random.default_rng(seed)
    coarse = np.ones((rows, cols), dtype=bool)
    coarse.ravel()[rng.choice(rows * cols, size=obstacles, replace=False)] = False
    grid = OccupancyGrid(expand(coarse), name=f"random-{rows}x{cols}-{obstacles}-{seed}")
    return work_area(grid, random_starts(grid, k, seed))


def instances(worlds: list[str], k: int, seeds: int,
              first: int = 0) -> Iterator[tuple[str, WorkArea, int]]:
    for world in worlds:
        for seed in range(first, first + seeds):
            if world.startswith("gen") and world[3:].isdigit():
                obstacles = int(world[3:])
                yield f"20x30 {obstacles} obst.", generated(20, 30, obstacles, k, seed), seed
            else:  # a builtin or generated world of planner.maps, e.g. office, city:64x64:3
                grid = resolve_world(world)
                yield world, work_area(grid, random_starts(grid, k, seed)), seed


def make(algo: str, area: WorkArea, seed: int) -> Plan:
    tree = build_tree(area.cells, "dfs", seed=seed, starts=[cell_of(s) for s in area.starts])
    plan: Plan = algorithm(algo).load_plan()(area, tree, algo, seed)
    return plan


def step_at(result: TakeoverResult, fraction: float) -> int:
    """First step at which ``fraction`` of the sub-cells are covered."""
    times = np.sort(result.first_time[result.first_time >= 0])
    return int(times[max(math.ceil(fraction * times.size) - 1, 0)])


def traffic(result: TakeoverResult) -> tuple[int, int, int]:
    """Waits, detours and bumps of one run, summed over its robots."""
    return (sum(c.waits for c in result.traffic), sum(c.detours for c in result.traffic),
            sum(c.bumps for c in result.traffic))


def traffic_cell(rows: list[tuple[float, ...]]) -> str:
    """Mean waits/detours/bumps per run (the last three columns of ``rows``), and the most
    of all three in one run."""
    w, d, b = (statistics.mean(r[i] for r in rows) for i in (-3, -2, -1))
    return f"{w:.1f}/{d:.1f}/{b:.1f} (≤{max(int(sum(r[-3:])) for r in rows)})"


def measure(algo: str, area: WorkArea, seed: int, fraction: float) -> list[tuple[float, ...]]:
    """(takeover, rebalance, ideal) ratios to the fault-free makespan and the rebalanced
    run's waits, detours and bumps, one row per death."""
    plan = make(algo, area, seed)
    replay = algorithm(algo).load_lockstep()
    free_run = replay(plan, {})
    at = step_at(free_run, fraction)
    base = plan.makespan
    rows = []
    for rp in plan.robots:
        left = max(rp.steps - at, 0)
        ideal = base + left / (plan.k - 1)
        out: list[float] = []
        for recovery in ("takeover", "rebalance"):
            result = replay(plan, {rp.robot: at}, recovery=recovery)
            assert result.complete, (algo, area.grid.name, rp.robot, recovery)
            out.append(result.coverage_time / base)
        rows.append((*out, ideal / base, *traffic(result)))
    return rows


def measure_half(algo: str, area: WorkArea, seed: int) -> list[tuple[float, ...]]:
    """(takeover, rebalance) coverage time over the ideal, k/2 deaths at random steps."""
    plan = make(algo, area, seed)
    replay = algorithm(algo).load_lockstep()
    rng = np.random.default_rng(10_000 + seed)
    dead = rng.choice(plan.k, size=plan.k // 2, replace=False)
    failures = {plan.robots[int(i)].robot: int(rng.integers(0, plan.makespan)) for i in dead}
    left = sum(max(plan.robots[int(i)].steps - failures[plan.robots[int(i)].robot], 0)
               for i in dead)
    ideal = plan.makespan + left / (plan.k - len(dead))
    out: list[float] = []
    for recovery in ("takeover", "rebalance"):
        result = replay(plan, failures, recovery=recovery)
        assert result.complete, (algo, area.grid.name, failures, recovery)
        out.append(result.coverage_time / ideal)
    return [(*out, *traffic(result))]


def main_half(args: argparse.Namespace) -> None:
    worlds = args.worlds.split(",")
    print(f"k/2 deaths at random steps, k = {args.k}, {args.seeds} seeds; coverage time / "
          f"ideal (fault-free + the dead robots' remaining moves shared by the survivors)")
    print(f"{'world':<18} {'algo':<9} {'takeover':>15} {'rebalance':>15} {'w/d/b':>18}")
    for algo in args.algos.split(","):
        by_world: dict[str, list[tuple[float, ...]]] = {}
        for name, area, seed in instances(worlds, args.k, args.seeds, args.first_seed):
            by_world.setdefault(name, []).extend(measure_half(algo, area, seed))
        for name, rows in by_world.items():
            take, rebal = [r[0] for r in rows], [r[1] for r in rows]
            print(f"{name:<18} {algo:<9} {statistics.mean(take):>6.2f} (≤{max(take):.2f}) "
                  f"{statistics.mean(rebal):>6.2f} (≤{max(rebal):.2f}) "
                  f"{traffic_cell(rows):>18}")


def main_replan_scale(spec: str, k: int) -> None:
    """CPU of one re-plan (planner.offline.rebalance) on a large map: robot 2 dies when
    every robot has walked 30 % and 60 % of its balanced plan (the agents each compute it)."""
    from planner.offline.rebalance import frozen_at, plan_order, rebalance

    grid = resolve_world(spec)
    area = work_area(grid, random_starts(grid, k, 1))
    plan = make("balanced", area, 1)
    cycle = plan.cycle
    print(f"one re-plan on {spec}, k = {k}, n = {area.n} sub-cells, balanced plan of "
          f"{plan.makespan} moves")
    for fraction in (0.3, 0.6):
        walked = {rp.robot: int(len(rp.path) * fraction) for rp in plan.robots}
        covered, survivors = frozen_at(plan, walked, {2})
        started = time.process_time()
        replan = rebalance(cycle, covered, survivors, plan_order(plan))
        print(f"at {fraction:.0%}: re-plan makespan {replan.makespan} moves, "
              f"CPU {time.process_time() - started:.2f} s")


def world_and_k(text: str) -> tuple[str, int]:
    spec, _, k = text.rpartition(":")
    if not spec or not k.isdigit() or int(k) < 2:
        raise argparse.ArgumentTypeError(f"{text!r}: want WORLD:K, e.g. rooms:120x120:1:100")
    return spec, int(k)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--algos", default="opt,balanced")
    parser.add_argument("--worlds", default="office,gen0,gen60,gen120",
                        help="genN (20 x 30 with N random obstacle cells) and/or any world "
                             "mstc up takes (office, city:64x64:3, ...)")
    parser.add_argument("--k", type=int, default=6)
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--first-seed", type=int, default=0,
                        help="instances from this seed on (fresh ones: not 0-4)")
    parser.add_argument("--coverage", type=float, default=0.3)
    parser.add_argument("--half", action="store_true",
                        help="k/2 deaths at random times instead of one at --coverage")
    parser.add_argument("--replan-scale", metavar="WORLD:K", type=world_and_k,
                        help="instead: CPU of one re-plan on a large map, e.g. "
                             "rooms:120x120:1:100")
    args = parser.parse_args()
    if args.replan_scale:
        main_replan_scale(*args.replan_scale)
        return
    if args.half:
        main_half(args)
        return
    worlds = args.worlds.split(",")
    print(f"one death at {args.coverage:.0%} coverage, k = {args.k}, {args.seeds} seeds, "
          f"each robot in turn; coverage time / fault-free makespan")
    print(f"{'world':<18} {'algo':<9} {'fault-free':>10} {'takeover':>15} {'rebalance':>15} "
          f"{'ideal':>6} {'w/d/b':>18} {'s':>5}")
    for algo in args.algos.split(","):
        by_world: dict[str, list[tuple[float, ...]]] = {}
        base: dict[str, list[int]] = {}
        started = time.perf_counter()
        for name, area, seed in instances(worlds, args.k, args.seeds, args.first_seed):
            by_world.setdefault(name, []).extend(measure(algo, area, seed, args.coverage))
            base.setdefault(name, []).append(make(algo, area, seed).makespan)
        spent = (time.perf_counter() - started) / max(len(by_world), 1)
        for name, rows in by_world.items():
            take, rebal, ideal = ([r[i] for r in rows] for i in range(3))
            print(f"{name:<18} {algo:<9} {statistics.mean(base[name]):>10.0f} "
                  f"{statistics.mean(take):>6.2f} (≤{max(take):.2f}) "
                  f"{statistics.mean(rebal):>6.2f} (≤{max(rebal):.2f}) "
                  f"{statistics.mean(ideal):>6.2f} {traffic_cell(rows):>18} {spent:>5.1f}")


if __name__ == "__main__":
    main()
