"""Lockstep simulator throughput: simulated robot-moves per second, 10 robots on Cave.

Run: .venv/bin/python benchmarks/bench_lockstep.py [--robots 10] [--trials 20] [--world cave]
Prints moves/s (sub-cell moves executed) and robot-steps/s (live robots x steps, waits
included) over ``trials`` seeded random placements, plus the mean time per run. Times are
process CPU time of the fastest of ``repeat`` passes (as timeit does): the least disturbed
by other processes on a shared machine.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from planner.grid import coarsen, largest_component
from planner.maps.worlds import builtin_world
from planner.ormstc.lockstep import SimConfig, simulate
from planner.types import OccupancyGrid, SubCell


def random_starts(world: OccupancyGrid, k: int, seed: int) -> list[SubCell]:
    rng = np.random.default_rng(seed)
    cells = np.argwhere(largest_component(coarsen(world)))
    pick = rng.choice(len(cells), size=k, replace=False)
    return [(2 * int(cells[i][0]) + int(rng.integers(2)),
             2 * int(cells[i][1]) + int(rng.integers(2))) for i in pick]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--world", default="cave")
    parser.add_argument("--robots", type=int, default=10)
    parser.add_argument("--trials", type=int, default=20)
    parser.add_argument("--delay", type=int, default=1, help="max message delay in steps")
    parser.add_argument("--repeat", type=int, default=5, help="report the fastest repeat")
    args = parser.parse_args()
    world = builtin_world(args.world)
    placements = [random_starts(world, args.robots, seed) for seed in range(args.trials)]
    best = float("inf")
    moves = robot_steps = 0
    for _ in range(args.repeat):
        moves = robot_steps = 0
        elapsed = 0.0
        for seed, starts in enumerate(placements):
            config = SimConfig(seed=seed, delay=(1, args.delay))
            began = time.process_time()
            result = simulate(world, starts, config)
            elapsed += time.process_time() - began
            moves += sum(result.moves)
            robot_steps += result.steps * args.robots
        best = min(best, elapsed)
    print(f"{args.world}, {args.robots} robots, {args.trials} trials, max delay {args.delay}, "
          f"best of {args.repeat}: {moves / best:,.0f} moves/s, "
          f"{robot_steps / best:,.0f} robot-steps/s, {1000 * best / args.trials:.1f} ms per run")


if __name__ == "__main__":
    main()
