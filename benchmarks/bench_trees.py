"""Planning-time benchmark of Create Tree and TMSTC* (prints figures; targets are <= 1 s).

    .venv/bin/python benchmarks/bench_trees.py [--maps-dir ../shared/maps/tmstc] [--repeat 5]

1. Create Tree, alpha = 2, on the 20 x 30 grid with 30 robots (900 bridge sets).
2. TMSTC* on Denver_2 (53 x 53 tree cells) with 16 evenly placed robots: tiling, greedy
   merge, swap pass, time-balanced division; the paper's C++ planner takes 13-16 s.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from planner.createtree import create_tree
from planner.grid import coarsen, largest_component
from planner.maps import load_map
from planner.tmstc import divide
from planner.tmstc.improve import improve_turns
from planner.tmstc.merge import merge_bricks
from planner.tmstc.placement import even_starts
from planner.tmstc.tiling import brick_tiling


def timed(fn: Callable[[], Any], repeat: int) -> tuple[float, Any]:
    """Median CPU seconds of ``repeat`` calls, and the last result.

    CPU time (process_time) rather than wall time: the 2 cores are shared, and a loaded
    machine inflates wall time several-fold without the planner doing more work.
    """
    times, result = [], None
    for _ in range(repeat):
        started = time.process_time()
        result = fn()
        times.append(time.process_time() - started)
    return statistics.median(times), result


def bench_create_tree(repeat: int) -> None:
    rng = np.random.default_rng(0)
    cells = np.ones((20, 30), dtype=bool)
    subs = np.argwhere(np.ones((40, 60), dtype=bool))
    runs: list[float] = []
    walls: list[float] = []
    for seed in range(repeat):
        picks = subs[rng.choice(len(subs), size=30, replace=False)]
        starts = [(int(r) // 2, int(c) // 2) for r, c in picks]
        robots = [(int(r), int(c)) for r, c in picks]
        started, wall = time.process_time(), time.perf_counter()
        create_tree(cells, starts, alpha=2.0, seed=seed, start_subcells=robots)
        runs.append(time.process_time() - started)
        walls.append(time.perf_counter() - wall)
    print(f"create_tree 20x30, 30 robots, alpha=2 (900 bridge sets): CPU median "
          f"{statistics.median(runs):.3f} s, max {max(runs):.3f} s over {repeat} inputs "
          f"(wall median {statistics.median(walls):.3f} s)")


def bench_tmstc(maps_dir: Path, repeat: int) -> None:
    path = maps_dir / "Denver_2_1024.png"
    if not path.is_file():
        print(f"TMSTC* benchmark skipped: {path} not found")
        return
    cells = largest_component(coarsen(load_map(path, cell_size=10)))
    starts = list(even_starts(cells, 16))
    t_tile, tiling = timed(lambda: brick_tiling(cells), repeat)
    t_merge, merged = timed(lambda: merge_bricks(tiling), repeat)
    t_swap, tree = timed(lambda: improve_turns(merged), repeat)
    t_split, split = timed(lambda: divide(tree, starts, balance="time"), repeat)
    total = t_tile + t_merge + t_swap + t_split
    print(f"TMSTC* Denver_2 ({int(cells.sum())} cells, 16 robots): tiling {t_tile:.3f} s, "
          f"merge {t_merge:.3f} s, swaps {t_swap:.3f} s, division {t_split:.3f} s, "
          f"total {total:.3f} s (CPU, median of {repeat}); makespan {split.makespan_time:.1f} s")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--maps-dir", type=Path, default=Path("../shared/maps/tmstc"))
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    bench_create_tree(args.repeat)
    bench_tmstc(args.maps_dir, args.repeat)


if __name__ == "__main__":
    main()
