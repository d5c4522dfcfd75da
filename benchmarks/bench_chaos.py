"""The large robustness campaign for docs/chaos.md (not a test; nothing is asserted).

    .venv/bin/python benchmarks/bench_chaos.py run --trials 1000 --jobs 2 --out runs/chaos-big
    .venv/bin/python benchmarks/bench_chaos.py table runs/chaos-big/trials.jsonl

``run`` is ``mstc chaos`` over every scenario and every grid fleet algorithm (example world,
2-4 robots); ``table`` tabulates a trials.jsonl, also one of a campaign cut short, with the
trial count, so the table in the docs says what it rests on.
"""

from __future__ import annotations

import argparse
import asyncio
import sys
from collections import Counter
from pathlib import Path

from deploy.chaos.campaign import load_outcomes, run_campaign, table
from deploy.chaos.schedule import Campaign


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", required=True)
    run = sub.add_parser("run")
    run.add_argument("--trials", type=int, default=1000)
    run.add_argument("--seed", type=int, default=1)
    run.add_argument("--out", type=Path, default=Path("runs/chaos-big"))
    run.add_argument("--jobs", type=int, default=2, help="trials side by side (2)")
    run.add_argument("--first", type=int, default=0, help="first trial index (0): to go on "
                     "with a campaign that was cut short, appending to its trials.jsonl")
    tab = sub.add_parser("table")
    tab.add_argument("jsonl", type=Path)
    args = parser.parse_args(argv)
    if args.command == "run":
        outcomes = asyncio.run(run_campaign(
            Campaign(seed=args.seed), range(args.first, args.trials), args.out,
            lambda line: print(line, flush=True), jobs=args.jobs))
    else:
        outcomes = load_outcomes(args.jsonl)
    print(table(outcomes))
    print(f"{len(outcomes)} trials; verdicts {dict(Counter(o.verdict for o in outcomes))}")
    for o in outcomes:
        if o.verdict != "ok":
            print(f"  {o.verdict} trial {o.trial.index} {o.trial.algo} k={o.trial.robots} "
                  f"{o.trial.scenario}: {o.detail[:160]}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
