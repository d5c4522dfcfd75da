"""ORMSTC under forced collisions: lockstep runs that never end, or end with two owners.

Run: .venv/bin/python benchmarks/bench_forced_collisions.py [--first-seed 0] [--seeds 3000]
     [--size 4] [--wide [--deaths] [--safe-window]] [--half-sense]

Every run has a claim window of one step (below the safe bound, so claims collide) and
message delays of 1-6 steps. The default grid is the one that found the runs that never
ended (docs/ormstc.md, "Bodies that hold each other up"): per seed, worlds of ``size`` x
``size`` cells, 4, 5 and 6 robots, no obstacles or 15 %, both priorities (12 runs). With
``--wide`` each seed draws one run from the property test's space instead (4-8 cells a
side, 2-6 robots); ``--deaths`` then also kills 1 to k - 1 robots at random steps (3-6
robots), and ``--safe-window`` uses the simulator's safe claim window instead of one step.
``--half-sense`` answers as a thin sonar where the machine allows it (``SimConfig.half_sense``:
cells grown into on the half the walk enters and looked at from inside, planner/ormstc/inside.py).
Prints the runs, those that never ended (the simulator's step limit), those that ended
with a cell owned by two live robots and those that ended with a sub-cell missed (of the
free cells reachable from a survivor's start, not walled off by a dead body:
``deploy.repro_ormstc.missed_sub_cells``), with their parameters.
"""

from __future__ import annotations

import argparse
import random
import sys
import time
from collections.abc import Iterator

import numpy as np

from deploy.repro_ormstc import missed_sub_cells
from planner.grid import coarsen, largest_component
from planner.ormstc.lockstep import LockstepSim, SimConfig
from planner.ormstc.types import Cell, Priority
from planner.types import OccupancyGrid, SubCell

# seed, size, robots, density, priority, (robot, step it dies) for each death
Run = tuple[int, int, int, float, Priority, tuple[tuple[int, int], ...]]


def world_of(seed: int, size: int, density: float) -> OccupancyGrid:
    """The worlds of tests/test_ormstc_sim.py's ``random_world`` (same seed, same world)."""
    rng = np.random.default_rng(seed)
    return OccupancyGrid(rng.random((2 * size, 2 * size)) >= density, name=f"random-{seed}")


def starts_of(world: OccupancyGrid, k: int, seed: int) -> list[SubCell]:
    """The starts of tests/test_ormstc_sim.py's ``random_starts``."""
    rng = np.random.default_rng(seed + 1)
    cells = np.argwhere(largest_component(coarsen(world)))
    pick = rng.choice(len(cells), size=min(k, len(cells)), replace=False)
    return [(2 * int(cells[i][0]) + int(rng.integers(2)),
             2 * int(cells[i][1]) + int(rng.integers(2))) for i in pick]


def runs(first: int, seeds: int, size: int, wide: bool, deaths: bool) -> Iterator[Run]:
    for seed in range(first, first + seeds):
        if wide:
            draw = random.Random(seed)
            side = draw.randint(4, 8)
            k = draw.randint(3 if deaths else 2, 6)
            density, priority = draw.choice([0.0, 0.15]), draw.choice(list(Priority))
            dead = draw.sample(range(k), draw.randint(1, k - 1)) if deaths else []
            yield (seed, side, k, density, priority,
                   tuple((robot, draw.randint(0, 20 * side)) for robot in dead))
            continue
        for k in (4, 5, 6):
            for density in (0.0, 0.15):
                for priority in Priority:
                    yield seed, size, k, density, priority, ()


def two_owners(sim: LockstepSim, dead: set[int]) -> bool:
    """Whether a cell is owned by two live robots."""
    owned: set[Cell] = set()
    for machine in sim.machines:
        if machine.me in dead:
            continue
        cells = machine.mine.difference(machine.ceded)
        if owned & cells:
            return True
        owned |= cells
    return False


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--seeds", type=int, default=3000)
    parser.add_argument("--size", type=int, default=4, help="cells a side (default grid)")
    parser.add_argument("--wide", action="store_true",
                        help="one draw per seed from the property test's wider space")
    parser.add_argument("--deaths", action="store_true",
                        help="with --wide: kill 1 to k - 1 robots at random steps")
    parser.add_argument("--safe-window", action="store_true",
                        help="the simulator's safe claim window instead of one step")
    parser.add_argument("--half-sense", action="store_true",
                        help="a thin sonar's answers: grow on half a cell, look from inside")
    args = parser.parse_args()
    began = time.perf_counter()
    count, never, double, lost = 0, [], [], []
    window = None if args.safe_window else 1
    for run in runs(args.first_seed, args.seeds, args.size, args.wide, args.deaths):
        seed, size, k, density, priority, failures = run
        world = world_of(seed, size, density)
        starts = starts_of(world, k, seed)
        failures = tuple((robot, step) for robot, step in failures if robot < len(starts))
        sim = LockstepSim(world, starts, SimConfig(seed=seed, delay=(1, 6), claim_wait=window,
                                                   priority=priority, failures=failures,
                                                   half_sense=args.half_sense))
        result = sim.run()
        count += 1
        if not result.finished:
            never.append(run)
        elif two_owners(sim, set(result.deaths)):
            double.append(run)
        elif missed_sub_cells(result):
            lost.append(run)
        if count % 2000 == 0:
            print(f"  {count} runs, {len(never)} never ended, {len(double)} with two owners, "
                  f"{len(lost)} missed sub-cells", file=sys.stderr)
    print(f"{count} runs in {time.perf_counter() - began:.0f} s: {len(never)} never ended, "
          f"{len(double)} ended with two owners, {len(lost)} missed sub-cells")
    for label, found in (("never ended", never), ("two owners", double), ("missed", lost)):
        for seed, size, k, density, priority, failures in found:
            print(f"  {label}: seed {seed}, {size} x {size}, {k} robots, "
                  f"density {density}, priority {priority.name}, deaths {failures}")


if __name__ == "__main__":
    main()
