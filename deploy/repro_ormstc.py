"""``mstc repro-ormstc``: reproduce paper 004's Fig. 4 (ORMSTC coverage time vs team size).

Builtin worlds Cave and Room; 2, 4, 6, 8 and 10 robots; ``--trials`` seeded random starts
(one robot per cell) per point. Each placement runs three times in the lockstep simulator:
no failure, one robot killed, and k - 1 robots killed, the victims (seeded) dying half-way
through the failure-free run. Reports coverage time in moves (the most moves of any robot) and
in simulated seconds (RV-400 kinematics, one-direction sensing as on the paper's robot), with
standard deviations, and checks every run against the coverage oracle. Writes a CSV and a PNG.
"""

from __future__ import annotations

import argparse
import csv
import statistics
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bus import argtypes
from planner.errors import PlannerError
from planner.grid import coarsen, expand, label_components, largest_component
from planner.maps.worlds import builtin_world
from planner.ormstc.lockstep import SimConfig, SimResult, simulate
from planner.ormstc.types import SenseMode
from planner.types import OccupancyGrid, SubCell

WORLDS = ("cave", "room")
SCENARIOS = ("none", "one", "k-1")


@dataclass(frozen=True)
class Row:
    world: str
    k: int
    scenario: str
    trial: int
    steps: int
    moves: int
    seconds: float
    total_moves: int
    revisits: int
    missed: int


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--trials", type=int, default=10, help="trials per point (10)")
    parser.add_argument("--robots", default="2,4,6,8,10", help="comma-separated team sizes")
    parser.add_argument("--delay", type=int, default=1, help="max message delay in steps (1)")
    parser.add_argument("--seed", type=argtypes.seed, default=2006)
    parser.add_argument("--out", default="docs/img", help="folder for the CSV and PNG")


def random_starts(world: OccupancyGrid, k: int, rng: np.random.Generator) -> list[SubCell]:
    """k distinct cells of the largest free component, a random sub-cell in each."""
    cells = np.argwhere(largest_component(coarsen(world)))
    if len(cells) < k:
        raise PlannerError(f"{world.name}: {len(cells)} free cells, cannot place {k} robots")
    pick = rng.choice(len(cells), size=k, replace=False)
    return [(2 * int(cells[i][0]) + int(rng.integers(2)),
             2 * int(cells[i][1]) + int(rng.integers(2))) for i in pick]


def missed_sub_cells(result: SimResult) -> int:
    """Sub-cells reachable by the survivors (dead bodies block their cell) left uncovered."""
    free = coarsen(result.world).free.copy()
    for robot in result.deaths:
        r, c = result.paths[robot][-1]
        free[r // 2, c // 2] = False
    labels, _ = label_components(free)
    keep = {int(labels[r // 2, c // 2]) for i, (r, c) in enumerate(result.starts)
            if i not in result.deaths} - {0}
    need = np.zeros(result.world.shape, dtype=bool)
    mask = expand(np.isin(labels, list(keep)))
    need[: mask.shape[0], : mask.shape[1]] = mask
    return int((need & ~result.covered).sum())


def _row(world: str, k: int, scenario: str, trial: int, result: SimResult) -> Row:
    revisits = int(np.clip(result.visits - 1, 0, None).sum())
    return Row(world, k, scenario, trial, result.steps, result.makespan,
               round(max(result.seconds()), 1), sum(result.moves), revisits,
               missed_sub_cells(result))


def run_point(world: OccupancyGrid, k: int, trial: int, seed: int,
              delay: int) -> list[Row]:
    rng = np.random.default_rng(seed)
    starts = random_starts(world, k, rng)
    base = SimConfig(sense_mode=SenseMode.SINGLE, delay=(1, delay), seed=seed)
    clean = simulate(world, starts, base)
    if not clean.finished:
        raise PlannerError(f"{world.name}, k={k}, trial {trial}: the run did not finish")
    rows = [_row(world.name, k, "none", trial, clean)]
    half = clean.steps // 2
    order = [int(v) for v in rng.permutation(k)]
    for scenario, victims in (("one", order[:1]), ("k-1", order[: k - 1])):
        config = SimConfig(sense_mode=SenseMode.SINGLE, delay=(1, delay), seed=seed,
                           failures=tuple((v, half) for v in victims))
        result = simulate(world, starts, config)
        rows.append(_row(world.name, k, scenario, trial, result))
    return rows


def _write_csv(rows: list[Row], path: Path) -> None:
    with path.open("w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(list(Row.__dataclass_fields__))
        for r in rows:
            writer.writerow([r.world, r.k, r.scenario, r.trial, r.steps, r.moves, r.seconds,
                             r.total_moves, r.revisits, r.missed])


Summary = dict[tuple[str, str, int], tuple[float, float, float, float]]


def summarise(rows: list[Row]) -> Summary:
    """(world, scenario, k) -> (mean moves, sd moves, mean seconds, sd seconds)."""
    groups: dict[tuple[str, str, int], list[Row]] = {}
    for r in rows:
        groups.setdefault((r.world, r.scenario, r.k), []).append(r)
    out: Summary = {}
    for key, group in groups.items():
        moves = [float(r.moves) for r in group]
        secs = [r.seconds for r in group]
        sd = statistics.pstdev
        out[key] = (statistics.fmean(moves), sd(moves), statistics.fmean(secs), sd(secs))
    return out


def _plot(summary: Summary, teams: list[int], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(2, 3, figsize=(10, 5.6), sharex=True)
    for col, scenario in enumerate(SCENARIOS):
        for world, marker in zip(WORLDS, "os", strict=True):
            ks = [k for k in teams if (world, scenario, k) in summary]
            stats = [summary[(world, scenario, k)] for k in ks]
            axes[0][col].errorbar(ks, [s[0] for s in stats], yerr=[s[1] for s in stats],
                                  marker=marker, capsize=3, label=world.capitalize())
            axes[1][col].errorbar(ks, [s[2] for s in stats], yerr=[s[3] for s in stats],
                                  marker=marker, capsize=3, label=world.capitalize())
        title = {"none": "no failure", "one": "1 robot killed", "k-1": "k-1 robots killed"}
        axes[0][col].set_title(title[scenario], fontsize=10)
        axes[1][col].set_xlabel("robots")
    axes[0][0].set_ylabel("coverage time (moves)")
    axes[1][0].set_ylabel("coverage time (sim. s)")
    axes[0][0].legend(fontsize=8)
    for ax in axes.flat:
        ax.grid(alpha=0.3)
    fig.suptitle("ORMSTC, paper 004 Fig. 4 setting (mean ± sd)", fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def _picture(path: Path, seed: int) -> None:
    """One Cave run, 6 robots, the busiest killed half-way: who covered each sub-cell first."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    world = builtin_world("cave")
    starts = random_starts(world, 6, np.random.default_rng(seed))
    clean = simulate(world, starts, SimConfig(seed=seed))
    victim = int(np.argmax(clean.moves))
    half = clean.steps // 2
    result = simulate(world, starts, SimConfig(seed=seed, failures=((victim, half),)))
    fig, axes = plt.subplots(1, 2, figsize=(9, 3.4))
    for ax, res, title in ((axes[0], clean, "no failure"),
                           (axes[1], result, f"robot {victim} killed at step {half}")):
        shown = np.where(res.first_robot >= 0, res.first_robot, np.nan).astype(float)
        shown[~world.free] = np.nan
        ax.imshow(~world.free, cmap="Greys", vmin=0, vmax=1.5)
        ax.imshow(shown, cmap="tab10", vmin=0, vmax=9, alpha=0.85)
        for robot, (r, c) in enumerate(starts):
            ax.plot(c, r, "k*" if robot not in res.deaths else "rx", markersize=7)
        ax.set_title(f"{title}: {res.makespan} moves", fontsize=9)
        ax.set_xticks([])
        ax.set_yticks([])
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)


def run(args: argparse.Namespace) -> int:
    if args.trials < 1 or args.delay < 1:
        raise PlannerError("--trials and --delay must be at least 1")
    try:
        teams = [int(k) for k in args.robots.split(",") if k]
    except ValueError as exc:
        raise PlannerError(f"--robots: expected comma-separated integers ({exc})") from exc
    if not teams or min(teams) < 1:
        raise PlannerError("--robots: give at least one team size of 1 or more")
    rows: list[Row] = []
    for w_index, name in enumerate(WORLDS):
        world = builtin_world(name)
        for k in teams:
            for trial in range(args.trials):
                seed = args.seed * 100_003 + w_index * 10_007 + k * 101 + trial
                rows.extend(run_point(world, k, trial, seed, args.delay))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    _write_csv(rows, out / "ormstc_fig4.csv")
    summary = summarise(rows)
    print(f"{'world':6} {'k':>3} {'scenario':8} {'moves':>14} {'seconds':>16}")
    ordered = sorted(summary.items(), key=lambda item: (
        item[0][0], SCENARIOS.index(item[0][1]), item[0][2]))
    for (name, scenario, k), (mm, sm, ms, ss) in ordered:
        print(f"{name:6} {k:3d} {scenario:8} {mm:8.1f} ±{sm:5.1f} {ms:9.1f} ±{ss:6.1f}")
    missed = sum(r.missed for r in rows)
    print(f"{len(rows)} runs, {missed} reachable sub-cells left uncovered in total")
    try:
        _plot(summary, teams, out / "ormstc_fig4.png")
        _picture(out / "ormstc_cave_example.png", args.seed)
    except ImportError:
        print(f"wrote {out / 'ormstc_fig4.csv'} (install matplotlib for the PNG)")
        return 0
    print(f"wrote {out / 'ormstc_fig4.csv'} and {out / 'ormstc_fig4.png'}")
    return 0 if missed == 0 else 1
