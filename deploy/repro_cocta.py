"""``mstc repro-cocta``: reproduce paper 001's Fig. 4 (NCOCTA vs COCTA) as CSV and PNG."""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

from planner.treecover.loop import run_loop_iterations
from planner.treecover.sim import run_coverage
from planner.treecover.trees import general_tree, perfect_tree

FULL_ROBOTS = list(range(5, 61, 5))
QUICK_ROBOTS = [5, 15, 30, 60]
PERFECT = [(2, 15), (3, 8), (4, 8)]
QUICK_PERFECT = [(2, 11), (3, 6), (4, 5)]
EXAMPLE = [(16, "ncocta"), (20, "ncocta"), (16, "cocta"), (20, "cocta")]  # sec. 4.2 / 4.3


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--out", default="docs/results", help="directory for CSV and PNG")
    parser.add_argument("--quick", action="store_true", help="smaller trees, fewer points")
    parser.add_argument("--seeds", type=int, default=None,
                        help="random trees per (removed, height) point (default 3; quick 1)")


def run(args: argparse.Namespace) -> int:
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    perfect = _perfect_sweep(QUICK_PERFECT if args.quick else PERFECT,
                             QUICK_ROBOTS if args.quick else FULL_ROBOTS)
    heights = _height_sweep(range(5, 11 if args.quick else 16))
    seeds = args.seeds if args.seeds is not None else (1 if args.quick else 3)
    general = _general_sweep([10] if args.quick else [10, 12], seeds)
    example = [_row(3, 7, k, algo) for k, algo in EXAMPLE]
    _write(out / "cocta_example.csv", example)
    _write(out / "cocta_perfect.csv", perfect)
    _write(out / "cocta_heights.csv", heights)
    _write(out / "cocta_general.csv", general)
    _plot(out, perfect, heights, general)
    for row in example:
        print(f"3-ary H=7, {row['robots']} robots, {row['algo']}: SF {row['speedup']:.2f} "
              f"(edge steps), {row['loop_speedup']:.2f} (loop iterations)")
    print(f"wrote {out}/cocta_*.csv and .png in {time.perf_counter() - started:.1f} s")
    return 0


def _row(n: int, h: int, robots: int, algo: str, **extra: object) -> dict[str, object]:
    """One run per clock: edge steps (``time``) and iterations of the paper's loop."""
    tree = perfect_tree(n, h)
    result = run_coverage(tree, robots, algo)
    loop = run_loop_iterations(tree, robots, algo)
    if not (result.connected and loop.connected):
        raise RuntimeError(f"connectivity broken: N={n} H={h} k={robots} {algo}")
    return {"N": n, "H": h, "robots": robots, "algo": algo, "time": result.time,
            "speedup": round(result.speedup, 4),
            "splits": " ".join(map(str, result.splits.heights)),
            "loop_time": loop.time, "loop_speedup": round(loop.speedup, 4),
            **extra}


def _perfect_sweep(trees: list[tuple[int, int]], robots: list[int]) -> list[dict[str, object]]:
    return [_row(n, h, k, algo) for n, h in trees for k in robots
            for algo in ("ncocta", "cocta")]


def _height_sweep(heights: range) -> list[dict[str, object]]:
    return [_row(2, h, 60, algo) for h in heights for algo in ("ncocta", "cocta")]


def _general_sweep(heights: list[int], seeds: int) -> list[dict[str, object]]:
    rows: list[dict[str, object]] = []
    for h in heights:
        for removed in (0, 3, 6, 9, 12, 15):
            times, speedups = [], []
            for at in range(7):  # the paper's 7 cut heights
                for seed in range(seeds):
                    tree = general_tree(2, h, removed, at, seed) if removed else perfect_tree(2, h)
                    result = run_coverage(tree, 60, "cocta")
                    if not result.connected:
                        raise RuntimeError(f"connectivity broken on {tree.name}")
                    times.append(result.time)
                    speedups.append(result.speedup)
            rows.append({"H": h, "removed": removed, "runs": len(times),
                         "mean_time": round(sum(times) / len(times), 1),
                         "mean_speedup": round(sum(speedups) / len(speedups), 4)})
    return rows


def _write(path: Path, rows: list[dict[str, object]]) -> None:
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)


def _plot(out: Path, perfect: list[dict[str, object]], heights: list[dict[str, object]],
          general: list[dict[str, object]]) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    trees = sorted({(int(r["N"]), int(r["H"])) for r in perfect})  # type: ignore[call-overload]
    fig, axes = plt.subplots(2, len(trees) + 1, figsize=(13, 6))
    for col, (n, h) in enumerate(trees):
        for algo in ("ncocta", "cocta"):
            rows = [r for r in perfect if r["N"] == n and r["H"] == h and r["algo"] == algo]
            ks = [r["robots"] for r in rows]
            line, = axes[0, col].plot(ks, [r["speedup"] for r in rows], marker=".",
                                      label=algo)
            axes[0, col].plot(ks, [r["loop_speedup"] for r in rows], linestyle="--",
                              color=line.get_color(), label=f"{algo} (loop iterations)")
            axes[1, col].plot(ks, [r["time"] for r in rows], marker=".", label=algo)
        axes[0, col].set_title(f"{n}-ary, H={h}")
        axes[1, col].set_xlabel("robots")
    for algo in ("ncocta", "cocta"):
        rows = [r for r in heights if r["algo"] == algo]
        axes[0, -1].plot([r["H"] for r in rows], [r["speedup"] for r in rows], marker=".",
                         label=algo)
        axes[1, -1].plot([r["H"] for r in rows], [r["time"] for r in rows], marker=".",
                         label=algo)
    axes[0, -1].set_title("2-ary, 60 robots")
    axes[1, -1].set_xlabel("height")
    axes[1, -1].set_yscale("log")
    axes[0, 0].set_ylabel("speedup factor")
    axes[1, 0].set_ylabel("coverage time (steps)")
    axes[0, 0].legend()
    fig.tight_layout()
    fig.savefig(out / "cocta_fig4.png", dpi=70)
    plt.close(fig)
    fig, (left, right) = plt.subplots(1, 2, figsize=(9, 3.2))
    for h in sorted({int(r["H"]) for r in general}):  # type: ignore[call-overload]
        rows = [r for r in general if r["H"] == h]
        left.plot([r["removed"] for r in rows], [r["mean_speedup"] for r in rows], marker=".",
                  label=f"H={h}")
        right.plot([r["removed"] for r in rows], [r["mean_time"] for r in rows], marker=".",
                   label=f"H={h}")
    left.set_ylabel("mean SF (COCTA, 60 robots)")
    right.set_ylabel("mean coverage time")
    for ax in (left, right):
        ax.set_xlabel("nodes removed")
        ax.legend()
    fig.tight_layout()
    fig.savefig(out / "cocta_general.png", dpi=70)
    plt.close(fig)
