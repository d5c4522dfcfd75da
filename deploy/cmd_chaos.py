"""``mstc chaos``: a seeded robustness campaign against real fleets on this host.

N trials over worlds, algorithms (the registry's, as fleets) and team sizes, each with a
fault schedule (deploy.chaos.schedule): kills from start-up on, hangs shorter and longer
than the death timeout, message loss (bus.faults), router restarts and freezes, partitions.
Each trial is judged from simhw's ground truth and from its recording; the end is a table, a
JSON Lines file (OUT/trials.jsonl) and, for each trial that was not ok, the command that
re-runs it alone. Exit status 1 when a trial was not ok.
"""

from __future__ import annotations

import argparse
import asyncio
import time
from pathlib import Path

from bus import argtypes
from deploy.chaos.schedule import GRID_FLEET
from deploy.errors import UsageError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from deploy.chaos.schedule import SCENARIOS

    parser.add_argument("--trials", type=int, default=20, help="number of trials (20)")
    parser.add_argument("--only", type=int, default=None, metavar="I",
                        help="run trial I alone (the command printed for a failing trial)")
    parser.add_argument("--seed", type=argtypes.seed, default=0, help="campaign seed (0)")
    parser.add_argument("--worlds", default="example",
                        help="comma-separated builtin worlds, generated worlds "
                             "(rooms:12x16:3, maze:11x15:1, ...) or map files (example)")
    parser.add_argument("--algos", default=",".join(GRID_FLEET),
                        help=f"comma-separated algorithms ({','.join(GRID_FLEET)})")
    parser.add_argument("--sizes", default="2,3,4", help="comma-separated team sizes (2,3,4)")
    parser.add_argument("--scenarios", default=",".join(SCENARIOS),
                        help="comma-separated fault scenarios, taken in turn "
                             f"({','.join(SCENARIOS)})")
    parser.add_argument("--jobs", type=int, default=1, metavar="J",
                        help="trials run side by side (1); each has its own router and port, "
                             "a host-starving trial runs alone")
    parser.add_argument("--out", type=Path, default=None, metavar="DIR",
                        help="trial directories and trials.jsonl (runs/chaos-<time>)")


def _campaign(args: argparse.Namespace) -> object:
    from deploy.chaos.partition import partition_problem
    from deploy.chaos.schedule import SCENARIOS, Campaign
    from planner.errors import PlannerError
    from planner.maps import resolve_world

    def items(text: str) -> tuple[str, ...]:
        return tuple(p.strip() for p in text.split(",") if p.strip())

    algos = items(args.algos)
    for name in algos:
        if name not in GRID_FLEET:
            raise UsageError(f"--algos: {name!r} is not a grid fleet algorithm; choose from "
                             f"{', '.join(GRID_FLEET)}")
    scenarios = items(args.scenarios)
    for name in scenarios:
        if name not in SCENARIOS:
            raise UsageError(f"--scenarios: unknown {name!r}; choose from {', '.join(SCENARIOS)}")
    problem = partition_problem() if "partition" in scenarios else None
    if problem is not None:
        print(f"mstc chaos: no partitions: {problem}")
        scenarios = tuple(s for s in scenarios if s != "partition")
    try:
        sizes = tuple(int(k) for k in items(args.sizes))
    except ValueError:
        raise UsageError(f"--sizes: expected integers, got {args.sizes!r}") from None
    if not sizes or min(sizes) < 1:
        raise UsageError("--sizes: team sizes are >= 1")
    worlds = items(args.worlds)
    if not worlds:
        raise UsageError("--worlds: name at least one world")
    for world in worlds:
        try:
            resolve_world(world)
        except PlannerError as exc:  # a map that cannot be read or made: the user's to fix
            raise UsageError(f"--worlds: {exc}") from None
    return Campaign(seed=args.seed, worlds=worlds, algos=algos, sizes=sizes,
                    scenarios=scenarios)


def run(args: argparse.Namespace) -> int:
    from deploy.chaos.campaign import closing_lines, run_campaign, table
    from deploy.chaos.schedule import Campaign

    if args.jobs < 1:
        raise UsageError("--jobs: at least 1")
    if args.trials < 1:
        raise UsageError("--trials: at least 1")
    if args.only is not None and args.only < 0:
        raise UsageError("--only: a trial index, 0 or more")
    campaign = _campaign(args)
    assert isinstance(campaign, Campaign)
    out = args.out or Path("runs") / time.strftime("chaos-%Y%m%d-%H%M%S")
    indices = [args.only] if args.only is not None else list(range(args.trials))
    print(f"mstc chaos: {len(indices)} trials, seed {campaign.seed}, {args.jobs} at a time, "
          f"out {out}", flush=True)
    outcomes = asyncio.run(run_campaign(campaign, indices, out,
                                        lambda line: print(line, flush=True), jobs=args.jobs))
    print(table(outcomes))
    print(f"trials: {out / 'trials.jsonl'}")
    for line in closing_lines(campaign, outcomes, out):
        print(line)
    return 1 if any(o.verdict != "ok" for o in outcomes) else 0
