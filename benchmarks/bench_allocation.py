"""Allocation timings (nb, bt, opt) and the paper's Fig. 4-a experiment in cycle-index space.

    .venv/bin/python benchmarks/bench_allocation.py            # timings
    .venv/bin/python benchmarks/bench_allocation.py --figure   # also average makespans
    .venv/bin/python benchmarks/bench_allocation.py --figure --plot docs/img/allocation_fig4a.png
    .venv/bin/python benchmarks/bench_allocation.py --worst    # exhaustive worst cases

Random starts are distinct uniform cycle indices drawn from --seed. On an empty 30 x 20 cell
grid every sub-cell lies on the STC cycle exactly once, so uniform random sub-cells are uniform
random indices whatever the tree: the averages reproduce paper 003's Fig. 4-a setting.
"""

from __future__ import annotations

import argparse
import itertools
import math
import statistics
import time
from collections.abc import Sequence

import numpy as np

from planner.allocation import allocate

SIZES = ((2400, 30, 0.010), (160_000, 100, 1.0))  # (n, k, target seconds for opt)
ALGOS = ("nb", "bt", "opt")


def positions(rng: np.random.Generator, n: int, k: int) -> list[int]:
    return [int(p) for p in rng.choice(n, size=k, replace=False)]


def timed(algo: str, n: int, starts: Sequence[int],
          speeds: Sequence[float] | None = None) -> tuple[float, int]:
    """Seconds for one allocate call and the makespan in moves."""
    t0 = time.perf_counter()
    allocations = allocate(algo, n, starts, speeds=speeds)
    elapsed = time.perf_counter() - t0
    return elapsed, max(a.steps for a in allocations)


def bench_sizes(seed: int, trials: int) -> None:
    print(f"median / max wall time over {trials} random placements (seed {seed})")
    for n, k, target in SIZES:
        rng = np.random.default_rng(seed)
        placements = [positions(rng, n, k) for _ in range(trials)]
        for algo in ALGOS:
            times = [timed(algo, n, p)[0] for p in placements]
            note = f"  (target <= {target * 1e3:g} ms)" if algo == "opt" else ""
            print(f"  n={n:>7} k={k:>3} {algo:>3}: median {statistics.median(times) * 1e3:8.2f} "
                  f"ms, max {max(times) * 1e3:8.2f} ms{note}")
        speeds = [float(s) for s in rng.choice([0.5, 1.0, 1.5, 2.0], size=k)]
        times = [timed("opt", n, p, speeds)[0] for p in placements]
        print(f"  n={n:>7} k={k:>3} opt with speeds in {{0.5, 1, 1.5, 2}}: median "
              f"{statistics.median(times) * 1e3:8.2f} ms, max {max(times) * 1e3:8.2f} ms")


def figure(seed: int, trials: int, n: int = 2400) -> dict[str, list[float]]:
    """Average makespan per k (Fig. 4-a), with the analytic best/worst-case curves."""
    rng = np.random.default_rng(seed)
    curves: dict[str, list[float]] = {"k": [], **{algo: [] for algo in ALGOS}}
    print(f"\naverage makespan (moves) over {trials} random placements, n = {n} (30 x 20 cells)")
    print("    k     nb     bt    opt   best ceil(n/k)-1   nb worst n-k   bt worst n/2-1")
    for k in range(3, 31, 3):
        sums = dict.fromkeys(ALGOS, 0)
        for _ in range(trials):
            p = positions(rng, n, k)
            for algo in ALGOS:
                sums[algo] += timed(algo, n, p)[1]
        avg = {algo: sums[algo] / trials for algo in ALGOS}
        curves["k"].append(k)
        for algo in ALGOS:
            curves[algo].append(avg[algo])
        print(f"  {k:3d} {avg['nb']:6.0f} {avg['bt']:6.0f} {avg['opt']:6.0f} "
              f"{math.ceil(n / k) - 1:18d} {n - k:14d} {n // 2 - 1:16d}")
    return curves


def plot(curves: dict[str, list[float]], out: str, n: int = 2400) -> None:
    """A small PNG of the averages next to the analytic curves."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ks = curves["k"]
    fig, ax = plt.subplots(figsize=(5, 3.2), dpi=80)
    ax.plot(ks, [n - k for k in ks], "k:", label="nb worst n-k")
    ax.plot(ks, [n / 2 - 1 for _ in ks], "k--", label="bt worst n/2-1")
    ax.plot(ks, [math.ceil(n / k) - 1 for k in ks], "k-", lw=0.8, label="best ceil(n/k)-1")
    for algo, style in zip(ALGOS, ("o-", "s-", "^-"), strict=True):
        ax.plot(ks, curves[algo], style, ms=4, label=f"{algo} (mean)")
    ax.set_xlabel("robots k")
    ax.set_ylabel("makespan (moves)")
    ax.set_title(f"n = {n} sub-cells, 100 random placements per k", fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out)
    print(f"plot written to {out}")


def worst_cases(sizes: Sequence[int] = (8, 16, 24, 32, 40)) -> None:
    """Worst makespan of bt and opt over every placement (up to rotation), k = 2..4."""
    print("\nworst case over every placement: n, then bt and opt for k = 2, 3, 4")
    print("    n   bt2 ceil(2n/3-1)  bt3  bt4 n/2-1   opt2 opt3 opt4")
    for n in sizes:
        worst = {}
        for algo, k in itertools.product(("bt", "opt"), (2, 3, 4)):
            worst[algo, k] = max(
                max(a.steps for a in allocate(algo, n, [0, *rest]))
                for rest in itertools.combinations(range(1, n), k - 1))
        print(f"  {n:3d} {worst['bt', 2]:5d} {math.ceil(2 * n / 3 - 1):12d} "
              f"{worst['bt', 3]:4d} {worst['bt', 4]:4d} {n / 2 - 1:5g}   "
              f"{worst['opt', 2]:4d} {worst['opt', 3]:4d} {worst['opt', 4]:4d}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=2024)
    parser.add_argument("--trials", type=int, default=21)
    parser.add_argument("--figure", action="store_true", help="also print Fig. 4-a averages")
    parser.add_argument("--plot", metavar="OUT.png", help="with --figure: draw the averages")
    parser.add_argument("--worst", action="store_true",
                        help="also print exhaustive bt/opt worst cases (small n)")
    args = parser.parse_args()
    bench_sizes(args.seed, args.trials)
    if args.worst:
        worst_cases()
    if args.figure:
        curves = figure(args.seed, 100)
        if args.plot:
            plot(curves, args.plot)


if __name__ == "__main__":
    main()
