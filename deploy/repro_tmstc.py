"""``mstc repro-tmstc``: reproduce paper 002 Table II (turns) and Table III (coverage time).

Table II: turns of the single-robot STC cycle for DFS, Kruskal and TMSTC* trees. Table III:
eq. 8 coverage time (Kobuki, Table I) of the slowest and fastest robot for TMSTC* (our tree,
time-balanced split) and MSTC* (Kruskal tree, moves-balanced split), robots placed evenly
(k-means) or at random. The maps are discretized as the paper did: 10 px per sub-cell.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path
from typing import Any

import numpy as np

from bus import argtypes
from planner.grid import coarsen, largest_component
from planner.maps import load_map
from planner.metrics import KOBUKI
from planner.tmstc import divide, tmstc_tree
from planner.tmstc.placement import even_starts, random_starts
from planner.tmstc.turns import tree_turns
from planner.trees import build_tree
from planner.types import BoolArray, SpanningTree, SubCell

Row = dict[str, Any]
MAPS = {  # name -> (file, robot counts of Table III)
    "Indoor": ("indoor_real.pgm", (1, 2, 3, 4, 5)),
    "Random": ("random_20_10.pgm", (1, 2, 3, 4, 5)),
    "Denver_2": ("Denver_2_1024.png", (1, 4, 8, 12, 16)),
    "NewYork_0": ("NewYork_0_1024.png", (1, 4, 8, 12, 16)),
}
PAPER_TURNS = {  # Table II: DFS, ACO, Kruskal, TMSTC*
    "Indoor": (296, 254, 272, 206), "Random": (296, 288, 258, 208),
    "Denver_2": (1000, 1076, 894, 652), "NewYork_0": (1180, 1440, 954, 780),
}
PAPER_TIMES = {  # Table III: (TMSTC* max, min, MSTC* max, min) seconds
    ("Indoor", 1): (2020.3, 2020.3, 2178.6, 2178.6),
    ("Indoor", 2): (1101.4, 1068.5, 1184.2, 1151.2),
    ("Indoor", 3): (738.4, 719.5, 795.8, 774.9), ("Indoor", 4): (576.7, 538.7, 629.3, 556.2),
    ("Indoor", 5): (466.8, 449.4, 516.5, 455.6),
    ("Random", 1): (1940.9, 1940.9, 2049.6, 2049.6),
    ("Random", 2): (1025.6, 1018.0, 1117.2, 1059.7),
    ("Random", 3): (724.9, 699.7, 804.3, 707.7), ("Random", 4): (542.2, 525.6, 633.8, 528.6),
    ("Random", 5): (456.9, 433.5, 511.0, 425.8),
    ("Denver_2", 1): (8027.9, 8027.9, 8851.7, 8851.7),
    ("Denver_2", 4): (2154.2, 2109.0, 2447.6, 2228.1),
    ("Denver_2", 8): (1129.2, 1066.0, 1318.4, 1132.8),
    ("Denver_2", 12): (790.2, 744.2, 904.9, 762.0),
    ("Denver_2", 16): (606.1, 546.0, 712.0, 552.3),
    ("NewYork_0", 1): (8484.9, 8484.9, 8851.7, 8851.7),
    ("NewYork_0", 4): (2234.6, 2187.4, 2447.6, 2228.1),
    ("NewYork_0", 8): (1198.6, 1138.3, 1318.4, 1132.8),
    ("NewYork_0", 12): (832.7, 771.5, 904.9, 762.0),
    ("NewYork_0", 16): (610.4, 578.2, 712.0, 552.3),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--maps-dir", type=Path, default=Path("../shared/maps/tmstc"))
    parser.add_argument("--out", type=Path, default=Path("docs/results"))
    parser.add_argument("--img", type=Path, default=None, help="PNG directory (default --out)")
    parser.add_argument("--placement", choices=("even", "random"), default="even")
    parser.add_argument("--placements", type=int, default=1,
                        help="random placements averaged per point (--placement random)")
    parser.add_argument("--tries", type=int, default=16,
                        help="greedy merges (seeded tie-breaks) kept best-of for 'ours best'")
    parser.add_argument("--seed", type=argtypes.seed, default=0)


def load_cells(path: Path) -> BoolArray:
    from planner.errors import MapFormatError

    if not path.is_file():
        raise MapFormatError(str(path), "map file not found (see --maps-dir)")
    return largest_component(coarsen(load_map(path, cell_size=10)))


def table2(name: str, cells: BoolArray, tries: int) -> tuple[Row, SpanningTree]:
    started = time.perf_counter()
    paper_tree = tmstc_tree(cells, tries=1, improve=False)
    paper_s = time.perf_counter() - started
    started = time.perf_counter()
    swapped = tmstc_tree(cells, tries=1, improve=True)
    swap_s = time.perf_counter() - started
    started = time.perf_counter()
    best = tmstc_tree(cells, tries=tries, improve=True)
    best_s = time.perf_counter() - started
    dfs_p, _, kruskal_p, ours_p = PAPER_TURNS[name]
    row = {
        "map": name, "cells": int(cells.sum()),
        "dfs": tree_turns(build_tree(cells, "dfs", seed=None)),
        "kruskal": tree_turns(build_tree(cells, "kruskal", seed=None)),
        "kruskal_seeded_mean": float(np.mean([tree_turns(build_tree(cells, "kruskal", seed=s))
                                              for s in range(10)])),
        "tmstc_greedy": tree_turns(paper_tree), "tmstc_swaps": tree_turns(swapped),
        f"tmstc_best_of_{tries}": tree_turns(best),
        "paper_dfs": dfs_p, "paper_kruskal": kruskal_p, "paper_tmstc": ours_p,
        "seconds_greedy": round(paper_s, 4), "seconds_swaps": round(swap_s, 4),
        "seconds_best": round(best_s, 3),
    }
    return row, best


def starts_for(cells: BoolArray, k: int, placement: str, seed: int) -> tuple[SubCell, ...]:
    if placement == "even":
        return even_starts(cells, k, seed=seed)
    return random_starts(cells, k, seed=seed)


def table3(name: str, cells: BoolArray, tree: SpanningTree, counts: tuple[int, ...],
           args: argparse.Namespace) -> list[Row]:
    kruskal = build_tree(cells, "kruskal", seed=None)
    rows = []
    runs = args.placements if args.placement == "random" else 1
    for k in counts:
        ours, theirs, seconds = [], [], []
        tree_only: list[float] = []
        split_only: list[float] = []
        for p in range(runs):
            starts = list(starts_for(cells, k, args.placement, args.seed + p))
            started = time.perf_counter()
            split = divide(tree, starts, balance="time", params=KOBUKI)
            seconds.append(time.perf_counter() - started)
            ours.append((split.makespan_time, split.min_time))
            base = divide(kruskal, starts, balance="moves", params=KOBUKI)
            theirs.append((base.makespan_time, base.min_time))
            # ablation: which half of TMSTC* (tree or time split) buys the gain
            tree_only.append(divide(tree, starts, balance="moves", params=KOBUKI).makespan_time)
            split_only.append(divide(kruskal, starts, balance="time", params=KOBUKI).makespan_time)
        paper = PAPER_TIMES[(name, k)]
        row = {"map": name, "robots": k, "placements": runs,
               "tmstc_max": round(float(np.mean([a for a, _ in ours])), 1),
               "tmstc_min": round(float(np.mean([b for _, b in ours])), 1),
               "mstc_star_max": round(float(np.mean([a for a, _ in theirs])), 1),
               "mstc_star_min": round(float(np.mean([b for _, b in theirs])), 1),
               "paper_tmstc_max": paper[0], "paper_tmstc_min": paper[1],
               "paper_mstc_star_max": paper[2], "paper_mstc_star_min": paper[3],
               "tmstc_tree_moves_split_max": round(float(np.mean(tree_only)), 1),
               "kruskal_time_split_max": round(float(np.mean(split_only)), 1),
               "division_seconds": round(float(np.mean(seconds)), 3)}
        rows.append(row)
        print(f"{name:9s} k={k:2d}: TMSTC* {row['tmstc_max']:7.1f} ({row['tmstc_min']:7.1f}) "
              f"paper {paper[0]:7.1f} ({paper[1]:7.1f}); MSTC* {row['mstc_star_max']:7.1f} "
              f"paper {paper[2]:7.1f}", flush=True)
    return rows


def write_csv(path: Path, rows: list[Row]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {path}")


def plot(rows: list[Row], trees: dict[str, SpanningTree], img: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    img.mkdir(parents=True, exist_ok=True)
    names = list(dict.fromkeys(str(r["map"]) for r in rows))
    fig, axes = plt.subplots(1, len(names), figsize=(3.3 * len(names), 3.2))
    for ax, name in zip(np.atleast_1d(axes), names, strict=True):
        part = [r for r in rows if r["map"] == name]
        ks = [r["robots"] for r in part]
        for key, label, style in (("tmstc_max", "TMSTC* ours", "-"),
                                  ("paper_tmstc_max", "TMSTC* paper", ":"),
                                  ("mstc_star_max", "MSTC* ours", "--"),
                                  ("paper_mstc_star_max", "MSTC* paper", "-.")):
            ax.plot(ks, [r[key] for r in part], style, marker=".", label=label)
        ax.set(title=name, xlabel="robots", ylabel="max coverage time (s)", yscale="log")
        ax.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(img / "tmstc_table3.png", dpi=60)
    plt.close(fig)
    if "Indoor" in trees:
        from planner.cycle import stc_cycle

        cycle = stc_cycle(trees["Indoor"])
        fig, ax = plt.subplots(figsize=(4.2, 3.6))
        path = np.vstack([cycle.path, cycle.path[:1]])
        ax.plot(path[:, 1], path[:, 0], lw=0.6)
        ax.set(title=f"TMSTC* cycle, Indoor ({tree_turns(trees['Indoor'])} turns)",
               aspect="equal")
        ax.invert_yaxis()
        ax.axis("off")
        fig.tight_layout()
        fig.savefig(img / "tmstc_indoor_cycle.png", dpi=60)
        plt.close(fig)


def run(args: argparse.Namespace) -> int:
    turns_rows, time_rows, trees = [], [], {}
    for name, (file, counts) in MAPS.items():
        cells = load_cells(args.maps_dir / file)
        row, tree = table2(name, cells, args.tries)
        turns_rows.append(row)
        trees[name] = tree
        print(f"{name:9s} turns: DFS {row['dfs']} Kruskal {row['kruskal']} TMSTC* greedy "
              f"{row['tmstc_greedy']} +swaps {row['tmstc_swaps']} best-of-{args.tries} "
              f"{row[f'tmstc_best_of_{args.tries}']} | paper {PAPER_TURNS[name]}", flush=True)
        time_rows += table3(name, cells, tree, counts, args)
    if args.placement == "even":
        write_csv(args.out / "tmstc_table2.csv", turns_rows)
    write_csv(args.out / f"tmstc_table3_{args.placement}.csv", time_rows)
    plot(time_rows, trees, args.img or args.out)
    return 0
