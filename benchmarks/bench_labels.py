"""Benchmark: component labelling, planner.grid.label_components against scipy's.

    .venv/bin/python benchmarks/bench_labels.py [--side 200] [--repeats 9]

label_components used scipy.sparse.csgraph.connected_components until 2026-12-01; it is now a
numpy hook-and-shortcut routine, so that agents do not import scipy (31 MB each). This prints,
per grid, the median time of the old scipy-based labelling (reproduced here, with the same
raster-order renumbering) and of the current one, on side x side coarse cells (200 x 200 =
40 000 cells, a 400 x 400 sub-cell map: the largest the benchmarks plan on), then the cost of
one call on a small 8 x 8 grid (tests and the balanced planner call it thousands of times).
Figures for docs/results.md; nothing is asserted.
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections.abc import Callable

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from planner.grid import label_components
from planner.types import BoolArray, IntArray

Labeller = Callable[[BoolArray], tuple[IntArray, int]]


def scipy_labels(free: BoolArray) -> tuple[IntArray, int]:
    """The labelling as it was: scipy's connected_components, renumbered in raster order."""
    h, w = free.shape
    flat = np.arange(h * w, dtype=np.int64).reshape(h, w)
    across = free[:, :-1] & free[:, 1:]
    down = free[:-1, :] & free[1:, :]
    u = np.concatenate([flat[:, :-1][across], flat[:-1, :][down]])
    v = np.concatenate([flat[:, 1:][across], flat[1:, :][down]])
    graph = coo_matrix((np.ones(len(u), dtype=np.int8), (u, v)), shape=(h * w, h * w))
    _, component = connected_components(graph, directed=False)
    free_flat = np.flatnonzero(free.ravel())
    labels = np.zeros(h * w, dtype=np.int64)
    if free_flat.size == 0:
        return labels.reshape(h, w), 0
    ids, first = np.unique(component[free_flat], return_index=True)
    renumber = np.zeros(int(component.max()) + 1, dtype=np.int64)
    renumber[ids[np.argsort(first)]] = np.arange(1, len(ids) + 1)
    labels[free_flat] = renumber[component[free_flat]]
    return labels.reshape(h, w), len(ids)


def serpentine(side: int) -> BoolArray:
    """One one-cell corridor through every other row: the longest path a square grid holds."""
    free = np.zeros((side, side), dtype=bool)
    free[::2, :] = True
    for r in range(1, side, 2):
        free[r, side - 1 if r % 4 == 1 else 0] = True
    return free


def grids(side: int) -> dict[str, BoolArray]:
    rng = np.random.default_rng(1)
    return {
        "open": np.ones((side, side), dtype=bool),
        "random 60 % free": rng.random((side, side)) < 0.6,
        "random 45 % free (many parts)": rng.random((side, side)) < 0.45,
        "serpentine corridor": serpentine(side),
        "checkerboard (all isolated)": np.add.outer(np.arange(side), np.arange(side)) % 2 == 0,
    }


def median_ms(label: Labeller, free: BoolArray, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        label(free)
        times.append(time.perf_counter() - start)
    return 1e3 * statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--side", type=int, default=200, help="coarse cells per side")
    parser.add_argument("--repeats", type=int, default=9)
    args = parser.parse_args()
    print(f"{args.side} x {args.side} cells, median of {args.repeats}: scipy (old) / numpy (now)")
    for name, free in grids(args.side).items():
        ours, theirs = label_components(free), scipy_labels(free)
        same = ours[1] == theirs[1] and np.array_equal(ours[0], theirs[0])
        print(f"  {name:32s} {median_ms(scipy_labels, free, args.repeats):7.2f} ms / "
              f"{median_ms(label_components, free, args.repeats):7.2f} ms  "
              f"({ours[1]} parts, {'same labels' if same else 'LABELS DIFFER'})")
    small = np.random.default_rng(2).random((8, 8)) < 0.6
    calls = 2000
    per_call = [1e3 * median_ms(f, small, calls) for f in (scipy_labels, label_components)]
    print(f"  8 x 8 grid, one call: {per_call[0]:.0f} us / {per_call[1]:.0f} us")


if __name__ == "__main__":
    main()
