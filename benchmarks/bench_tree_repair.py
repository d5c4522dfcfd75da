"""Trail repair of NCOCTA / COCTA: what a lost robot costs (figures for docs/treecover.md).

    .venv/bin/python benchmarks/bench_tree_repair.py [--runs 3] [--tree perfect:N=3,H=4]
        [--robots 8] [--at 20] [--fleet-victim 1]

Not a test; nothing asserted. Lockstep (planner.treecover.failures): coverage time without a
failure, and with each robot in turn lost at step ``--at`` (min / median / max over the
victims), how many of those losses cut the team for their step and how many made the
survivors re-plan. Fleet: ``mstc tree-fleet --kill VICTIM@AT`` ``--runs`` times (separate
processes on loopback): the step the agents removed the robot at, the coverage time and
whether it equals the lockstep run with that loss, mission seconds beside a run without kill.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile

from planner.treecover.failures import run_with_failures
from planner.treecover.sim import run_coverage
from planner.treecover.trees import tree_from_spec

MAIN = "import sys; from deploy.cli import main; sys.exit(main())"


def fleet(spec: str, robots: int, algo: str, kill: str | None) -> dict[str, object]:
    extra = ["--kill", kill] if kill else []
    with tempfile.TemporaryDirectory() as run_dir:
        done = subprocess.run(
            [sys.executable, "-c", MAIN, "tree-fleet", "--tree", spec, "--robots", str(robots),
             "--algo", algo, "--run-dir", run_dir, "--json", *extra],
            capture_output=True, text=True, timeout=600)
    if done.returncode != 0:
        raise SystemExit(f"{spec} k={robots} {algo} --kill {kill} failed:\n{done.stdout}"
                         f"{done.stderr}")
    summary: dict[str, object] = json.loads(done.stdout.strip().splitlines()[-1])
    return summary


def lockstep_table(spec: str, robots: int, at: int) -> None:
    tree = tree_from_spec(spec)
    print(f"lockstep, {spec}, k={robots}, one robot lost at step {at}")
    print(f"{'algo':<7} {'no loss':>7} {'min':>5} {'median':>6} {'max':>5} {'cut':>4} "
          f"{'replan':>6}")
    for algo in ("cocta", "ncocta"):
        plain = run_coverage(tree, robots, algo).time
        runs = [run_with_failures(tree, robots, algo, {victim: at}) for victim in range(robots)]
        times = [r.result.time for r in runs]
        cuts = sum(r.cut_at_death for r in runs)
        replans = sum(1 for r in runs if r.replans)
        print(f"{algo:<7} {plain:>7} {min(times):>5} {statistics.median(times):>6} "
              f"{max(times):>5} {cuts:>4} {replans:>6}")


def fleet_table(spec: str, robots: int, at: int, victim: int, runs: int) -> None:
    print(f"\nfleet, {spec}, k={robots}, --kill {victim}@{at}, {runs} runs each")
    print(f"{'algo':<7} {'kill':<5} {'removed at':>10} {'steps':>6} {'=lock':>5} "
          f"{'mission s':>9} {'cut':>4}")
    for algo in ("cocta", "ncocta"):
        for kill in (None, f"{victim}@{at}"):
            for _ in range(runs):
                s = fleet(spec, robots, algo, kill)
                deaths = s["deaths"]
                removed = ",".join(f"{r}@{t}" for r, t in dict(deaths).items()) \
                    if isinstance(deaths, dict) else ""
                print(f"{algo:<7} {'yes' if kill else 'no':<5} {removed or '-':>10} "
                      f"{s['coverage_time']!s:>6} {s['verdict'] == 'ok'!s:>5} "
                      f"{s['mission_seconds']!s:>9} {s['cut_at_death']!s:>4}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--tree", default="perfect:N=3,H=4")
    parser.add_argument("--robots", type=int, default=8)
    parser.add_argument("--at", type=int, default=20)
    parser.add_argument("--fleet-victim", type=int, default=1)
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    lockstep_table(args.tree, args.robots, args.at)
    if args.runs > 0:
        fleet_table(args.tree, args.robots, args.at, args.fleet_victim, args.runs)


if __name__ == "__main__":
    main()
