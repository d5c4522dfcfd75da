"""``mstc repro-createtree``: reproduce paper 000 section 3.3 (Create Tree vs random trees).

20 x 30 coarse grid, 0/40/80/100/160 random obstacle cells (kept connected), 3..30 robots at
random distinct sub-cells; NB-MSTC and optimal MSTC coverage time (makespan in moves) on a
Create Tree tree and on a uniformly random spanning tree of the same input. Also the
alpha = 1, 2, 3 comparison of Fig. 6 (13 % obstacles). Writes CSVs and PNGs to --out.
"""

from __future__ import annotations

import argparse
import csv
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from bus import argtypes
from deploy.errors import UsageError
from planner.allocation import allocate
from planner.createtree import MEASURES, create_tree
from planner.cycle import stc_cycle
from planner.grid import label_components
from planner.trees import build_tree
from planner.types import BoolArray, SpanningTree, SubCell

Row = dict[str, Any]
SHAPE = (20, 30)
OBSTACLES = (0, 40, 80, 100, 160)
PAPER = {  # section 3.3.2: improvement ratio at 30 robots, (NB, opt)
    0: (0.58, 0.38),
    160: (0.48, 0.28),
}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--inputs", type=int, default=300,
                        help="random inputs (robot placements) per point (paper: 300)")
    parser.add_argument("--robots", default="3-30",
                        help="robot counts: 'a-b' (every count), 'a-b/s' (step s) or 'a,b,c'")
    parser.add_argument("--obstacles", default=",".join(map(str, OBSTACLES)),
                        help="obstacle cell counts, comma-separated")
    parser.add_argument("--measure", choices=MEASURES, default="manhattan")
    parser.add_argument("--alpha", type=float, default=2.0)
    parser.add_argument("--alphas", default="1,2,3",
                        help="alphas for the Fig. 6 comparison ('' to skip it)")
    parser.add_argument("--alpha-inputs", type=int, default=None,
                        help="inputs per point for Fig. 6 (default: --inputs)")
    parser.add_argument("--bridge-rule", choices=("max", "power"), default="max",
                        help="bridge sets tried: max{k^alpha, N} (Alg. 1) or k^alpha (prose)")
    parser.add_argument("--part", choices=("all", "main", "alpha"), default="all",
                        help="run the Create Tree vs random experiment, the alpha one, or both")
    parser.add_argument("--seed", type=argtypes.seed, default=0)
    parser.add_argument("--out", type=Path, default=Path("docs/results"))
    parser.add_argument("--img", type=Path, default=None,
                        help="where the PNGs go (default: --out)")


def parse_counts(text: str) -> list[int]:
    """'3-30', '3-30/3' or '3,10,30' -> the list of counts."""

    try:
        if "-" in text:
            span, _, step = text.partition("/")
            lo, hi = (int(x) for x in span.split("-"))
            return list(range(lo, hi + 1, int(step) if step else 1))
        return [int(x) for x in text.split(",") if x.strip()]
    except ValueError as error:
        raise UsageError(f"bad count list {text!r}: {error}") from error


def obstacle_grid(count: int, rng: np.random.Generator) -> BoolArray:
    """The 20 x 30 grid with ``count`` random obstacle cells that leave it connected."""
    cells = np.ones(SHAPE, dtype=bool)
    placed = 0
    for flat in rng.permutation(cells.size).tolist():
        if placed == count:
            break
        r, c = divmod(flat, SHAPE[1])
        cells[r, c] = False
        if label_components(cells)[1] != 1:
            cells[r, c] = True  # this cell would cut the grid: leave it free
            continue
        placed += 1
    return cells


def random_robots(cells: BoolArray, k: int, rng: np.random.Generator) -> list[SubCell]:
    subs = np.argwhere(np.repeat(np.repeat(cells, 2, axis=0), 2, axis=1))
    picks = rng.choice(len(subs), size=k, replace=False)
    return [(int(subs[i][0]), int(subs[i][1])) for i in picks]


def makespans(tree: SpanningTree, robots: Sequence[SubCell]) -> tuple[int, int]:
    """NB-MSTC and optimal MSTC makespans (moves) on ``tree``."""
    cycle = stc_cycle(tree)
    positions = [cycle.position(s) for s in robots]
    nb, opt = (max(a.steps for a in allocate(algo, cycle.n, positions)) for algo in ("nb", "opt"))
    return nb, opt


def created(cells: BoolArray, robots: Sequence[SubCell], alpha: float, measure: str,
            seed: int, rule: str = "max") -> SpanningTree:
    return create_tree(cells, [(r // 2, c // 2) for r, c in robots], measure=measure,
                       alpha=alpha, seed=seed, start_subcells=robots, rule=rule)


def run_main(args: argparse.Namespace, robots: list[int], obstacles: list[int],
             out: Path) -> list[Row]:
    rows: list[Row] = []
    for count in obstacles:
        for k in robots:
            rng = np.random.default_rng([args.seed, count, k])
            nb_r, opt_r, nb_c, opt_c = [], [], [], []
            for i in range(args.inputs):
                cells = obstacle_grid(count, rng)
                starts = random_robots(cells, k, rng)
                a, b = makespans(build_tree(cells, "random", seed=int(rng.integers(2**31))),
                                 starts)
                nb_r.append(a)
                opt_r.append(b)
                tree = created(cells, starts, args.alpha, args.measure, i, args.bridge_rule)
                a, b = makespans(tree, starts)
                nb_c.append(a)
                opt_c.append(b)
            row = {"obstacles": count, "robots": k, "inputs": args.inputs,
                   "nb_random": float(np.mean(nb_r)), "nb_create": float(np.mean(nb_c)),
                   "opt_random": float(np.mean(opt_r)), "opt_create": float(np.mean(opt_c))}
            row["nb_gain"] = 1 - row["nb_create"] / row["nb_random"]
            row["opt_gain"] = 1 - row["opt_create"] / row["opt_random"]
            row["nb_create_below_opt_random"] = float(np.mean(np.array(nb_c) < np.array(opt_r)))
            rows.append(row)
            print(f"obstacles {count:3d} robots {k:2d}: NB {row['nb_random']:7.1f} -> "
                  f"{row['nb_create']:7.1f} ({row['nb_gain']:.0%}), opt {row['opt_random']:7.1f}"
                  f" -> {row['opt_create']:7.1f} ({row['opt_gain']:.0%})", flush=True)
    write_csv(out / "createtree_random_vs_create.csv", rows)
    return rows


def run_alphas(args: argparse.Namespace, robots: list[int], alphas: list[float],
               out: Path) -> list[Row]:
    rows: list[Row] = []
    inputs = args.alpha_inputs or args.inputs
    for k in robots:
        rng = np.random.default_rng([args.seed, 999, k])
        cases = []
        for _ in range(inputs):
            cells = obstacle_grid(80, rng)
            cases.append((cells, random_robots(cells, k, rng)))
        for alpha in alphas:
            started = time.perf_counter()
            spans = [makespans(created(c, s, alpha, args.measure, i, args.bridge_rule), s)
                     for i, (c, s) in enumerate(cases)]
            row = {"alpha": alpha, "robots": k, "inputs": inputs,
                   "nb": float(np.mean([a for a, _ in spans])),
                   "opt": float(np.mean([b for _, b in spans])),
                   "seconds_per_tree": (time.perf_counter() - started) / inputs}
            rows.append(row)
            print(f"alpha {alpha:g} robots {k:2d}: NB {row['nb']:7.1f} opt {row['opt']:7.1f} "
                  f"({row['seconds_per_tree']:.2f} s/tree)", flush=True)
    write_csv(out / f"createtree_alpha_{args.bridge_rule}.csv", rows)
    return rows


def write_csv(path: Path, rows: list[Row]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    print(f"wrote {path}")


def plot(main: list[Row], alphas: list[Row], img: Path, rule: str = "max") -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    img.mkdir(parents=True, exist_ok=True)
    if main:
        fig, axes = plt.subplots(1, 3, figsize=(13, 3.6))
        _plot_main(main, axes)
        fig.tight_layout()
        fig.savefig(img / "createtree_improvement.png", dpi=60)
        plt.close(fig)
    if alphas:
        fig, ax = plt.subplots(figsize=(5.5, 3.6))
        for alpha in sorted({r["alpha"] for r in alphas}):
            part = [r for r in alphas if r["alpha"] == alpha]
            for key, style in (("nb", "-"), ("opt", "--")):
                ax.plot([r["robots"] for r in part], [r[key] for r in part], style,
                        marker=".", label=f"{key.upper()} alpha={alpha:g}")
        ax.set(title=f"alpha, 80 obstacles, rule {rule} (cf. Fig. 6)", xlabel="robots",
               ylabel="makespan (moves)")
        ax.legend(fontsize=7)
        fig.tight_layout()
        fig.savefig(img / f"createtree_alpha_{rule}.png", dpi=60)
        plt.close(fig)


def _plot_main(main: list[Row], axes: Any) -> None:
    clean = [r for r in main if r["obstacles"] == main[0]["obstacles"]]
    ks = [r["robots"] for r in clean]
    for key, label in (("nb_random", "NB, random tree"), ("nb_create", "NB, Create Tree"),
                       ("opt_random", "opt, random tree"), ("opt_create", "opt, Create Tree")):
        axes[0].plot(ks, [r[key] for r in clean], marker=".", label=label)
    axes[0].set(title=f"makespan, {int(main[0]['obstacles'])} obstacles (cf. Fig. 7)",
                xlabel="robots", ylabel="makespan (moves)")
    axes[0].legend(fontsize=7)
    for ax, key, name in ((axes[1], "nb_gain", "NB-MSTC"), (axes[2], "opt_gain", "opt MSTC")):
        for count in sorted({r["obstacles"] for r in main}):
            part = [r for r in main if r["obstacles"] == count]
            ax.plot([r["robots"] for r in part], [100 * r[key] for r in part], marker=".",
                    label=f"{int(count)} obstacles")
        ax.set(title=f"{name} gain vs random trees (cf. Fig. 8)", xlabel="robots",
               ylabel="% shorter makespan")
        ax.legend(fontsize=7)


def run(args: argparse.Namespace) -> int:

    if args.inputs < 1:
        raise UsageError("--inputs must be at least 1")
    robots = parse_counts(args.robots)
    obstacles = parse_counts(args.obstacles)
    if any(k < 1 or k > 2 * SHAPE[0] * SHAPE[1] for k in robots):
        raise UsageError("robot counts must be between 1 and 1200")
    if any(c < 0 or c > 300 for c in obstacles):
        raise UsageError("obstacle counts must be between 0 and 300 (of 600 cells)")
    alphas = [float(a) for a in args.alphas.split(",") if a.strip()]
    main = run_main(args, robots, obstacles, args.out) if args.part in ("all", "main") else []
    alpha_rows = (run_alphas(args, robots, alphas, args.out)
                  if alphas and args.part in ("all", "alpha") else [])
    plot(main, alpha_rows, args.img or args.out, args.bridge_rule)
    for count, (nb, opt) in PAPER.items():
        ours = [r for r in main if r["obstacles"] == count and r["robots"] == max(robots)]
        if ours:
            print(f"{count} obstacles, {max(robots)} robots: NB gain {ours[0]['nb_gain']:.0%} "
                  f"(paper {nb:.0%} at 30), opt gain {ours[0]['opt_gain']:.0%} "
                  f"(paper {opt:.0%} at 30)")
    return 0
