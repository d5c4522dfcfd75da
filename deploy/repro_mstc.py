"""``mstc repro-mstc``: reproduce paper 003's Fig. 4 (random starts) and Fig. 5 (bases).

30 x 20 coarse grid (2400 sub-cells), empty and with 80 random obstacle cells; 3 to 30 robots;
100 seeded trials per point (``--trials`` for fewer); NB, BT and optimal MSTC on the same
random tree and starts. Writes a CSV and a PNG and prints a summary table.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

import numpy as np

from bus import argtypes
from planner.experiments.instances import grid_with_obstacles
from planner.experiments.mstc003 import ALGOS, Trial, analytic_curves, run_trial

ROWS, COLS = 20, 30


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--trials", type=int, default=100, help="trials per point (100)")
    parser.add_argument("--robots", default="3,6,9,12,15,18,21,24,27,30",
                        help="comma-separated team sizes")
    parser.add_argument("--bases", default="1,2,5",
                        help="base counts for the Fig. 5 experiment ('' to skip)")
    parser.add_argument("--seed", type=argtypes.seed, default=2005)
    parser.add_argument("--out", default="docs/results", help="folder for CSV and PNG")


def _trials(args: argparse.Namespace) -> list[Trial]:
    teams = [int(k) for k in args.robots.split(",") if k]
    bases = [int(b) for b in args.bases.split(",") if b]
    settings = [(obst, k, k) for obst in (0, 80) for k in teams]
    settings += [(0, k, b) for b in bases for k in teams if b < k]
    out: list[Trial] = []
    started = time.monotonic()
    for done, (obstacles, k, b) in enumerate(settings, 1):
        cells = grid_with_obstacles(ROWS, COLS, obstacles,
                                    np.random.default_rng(args.seed + obstacles))
        n = 4 * int(cells.sum())
        for trial in range(args.trials):
            seed = args.seed * 1_000_003 + obstacles * 10_007 + k * 101 + b * 7 + trial
            out.append(Trial(obstacles, k, b, trial, n, run_trial(cells, k, b, seed)))
        print(f"\r[{done}/{len(settings)}] obstacles={obstacles} k={k} bases={b} "
              f"({time.monotonic() - started:.0f} s)", end="", file=sys.stderr, flush=True)
    print(file=sys.stderr)
    return out


def _write_csv(trials: list[Trial], path: Path) -> None:
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["obstacles", "k", "bases", "trial", "n", *ALGOS])
        for t in trials:
            writer.writerow([t.obstacles, t.k, t.bases, t.trial, t.n, *t.makespans])


def _means(trials: list[Trial]) -> dict[tuple[int, int, int], tuple[int, np.ndarray]]:
    groups: dict[tuple[int, int, int], list[Trial]] = {}
    for t in trials:
        groups.setdefault((t.obstacles, t.k, t.bases), []).append(t)
    return {key: (g[0].n, np.mean([t.makespans for t in g], axis=0))
            for key, g in sorted(groups.items())}


def _plot(means: dict[tuple[int, int, int], tuple[int, np.ndarray]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    panels: list[tuple[int, int | None, str]] = [
        (0, None, "empty grid, random starts"), (80, None, "80 obstacle cells")]
    panels += [(0, b, f"empty grid, {b} base(s)")
               for b in sorted({key[2] for key in means if key[2] < key[1]})]
    fig, axes = plt.subplots(1, len(panels), figsize=(4.2 * len(panels), 3.6), squeeze=False)
    for ax, (obstacles, bases, title) in zip(axes[0], panels, strict=True):
        rows = [(k, n, m) for (o, k, b), (n, m) in means.items()
                if o == obstacles and (b == k if bases is None else b == bases)]
        ks = [r[0] for r in rows]
        for i, algo in enumerate(ALGOS):
            ax.plot(ks, [r[2][i] for r in rows], marker="o", label=algo)
        curves = [analytic_curves(r[1], r[0]) for r in rows]
        ax.plot(ks, [c["best"] for c in curves], "k--", linewidth=0.8, label="best case")
        ax.plot(ks, [c["bt_worst"] for c in curves], "k:", linewidth=0.8, label="BT worst")
        ax.set_title(title, fontsize="medium")
        ax.set_xlabel("robots")
        ax.set_ylim(bottom=0, top=max(max(r[2]) for r in rows) * 1.15)
    axes[0][0].set_ylabel("makespan (moves)")
    axes[0][0].legend(fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    trials = _trials(args)
    _write_csv(trials, out / "mstc003.csv")
    means = _means(trials)
    print(f"{'obst':>4} {'k':>3} {'bases':>5} {'n':>5} {'best':>6} "
          f"{'nb':>7} {'bt':>7} {'opt':>7}  opt vs nb")
    for (obstacles, k, bases), (n, m) in means.items():
        best = analytic_curves(n, k)["best"]
        print(f"{obstacles:4d} {k:3d} {bases:5d} {n:5d} {best:6.0f} "
              f"{m[0]:7.1f} {m[1]:7.1f} {m[2]:7.1f}  {100 * (1 - m[2] / m[0]):5.1f} % faster")
    try:
        _plot(means, out / "mstc003.png")
        print(f"wrote {out / 'mstc003.csv'} and {out / 'mstc003.png'}")
    except ImportError:
        print(f"wrote {out / 'mstc003.csv'} (install matplotlib for the PNG)")
    return 0
