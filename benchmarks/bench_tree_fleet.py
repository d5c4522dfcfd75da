"""NCOCTA / COCTA in the fleet: figures for docs/treecover.md (not a test; nothing asserted).

    .venv/bin/python benchmarks/bench_tree_fleet.py [--runs 2] [--case perfect:N=3,H=4:8:cocta]

Each run is one ``mstc tree-fleet --json`` (router, radio, k tree agents, all separate
processes on loopback; start-up included in the wall time). Printed per case: coverage time
in steps (and whether it equals the lockstep simulator's), wall seconds with start-up and
mission seconds (first report to the report completing coverage; medians of the runs),
steps per mission second, transmissions (copies robots put on their outboxes: k x k per step),
radio deliveries and refusals (copy, robot) pairs, and both per step.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile

DEFAULT_CASES = ("perfect:N=2,H=3:4:cocta", "perfect:N=3,H=4:8:cocta",
                 "perfect:N=3,H=4:8:ncocta", "perfect:N=2,H=6:10:cocta")
MAIN = "import sys; from deploy.cli import main; sys.exit(main())"


def run_case(spec: str, robots: int, algo: str) -> dict[str, object]:
    with tempfile.TemporaryDirectory() as run_dir:
        done = subprocess.run(
            [sys.executable, "-c", MAIN, "tree-fleet", "--tree", spec, "--robots", str(robots),
             "--algo", algo, "--run-dir", run_dir, "--json"],
            capture_output=True, text=True, timeout=600)
    if done.returncode != 0:
        raise SystemExit(f"{spec} k={robots} {algo} failed:\n{done.stdout}{done.stderr}")
    summary: dict[str, object] = json.loads(done.stdout.strip().splitlines()[-1])
    return summary


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=2)
    parser.add_argument("--case", action="append", metavar="SPEC:K:ALGO",
                        help="tree spec, robots and algorithm (repeatable)")
    args = parser.parse_args()
    print(f"{'tree':<22} {'k':>3} {'algo':<7} {'steps':>6} {'=lock':>5} {'wall s':>7} "
          f"{'mission':>7} {'steps/s':>8} {'tx':>7} {'deliv':>7} {'refused':>7} {'tx/step':>7} "
          f"{'dl/step':>7}")
    for case in args.case or DEFAULT_CASES:
        spec, robots, algo = case.rsplit(":", 2)
        runs = [run_case(spec, int(robots), algo) for _ in range(args.runs)]
        first = runs[0]
        steps = int(str(first["coverage_time"]))
        wall = statistics.median(float(str(r["wall_seconds"])) for r in runs)
        mission = statistics.median(float(str(r["mission_seconds"])) for r in runs)
        tx, dl = int(str(first["transmissions"])), int(str(first["deliveries"]))
        same = first["coverage_time"] == first["lockstep_time"]
        refused = first["refused_out_of_range"]
        print(f"{spec:<22} {robots:>3} {algo:<7} {steps:>6} {same!s:>5} {wall:>7.2f} "
              f"{mission:>7.2f} {steps / mission:>8.1f} {tx:>7} {dl:>7} {refused!s:>7} "
              f"{tx / (steps + 1):>7.1f} {dl / (steps + 1):>7.1f}")

if __name__ == "__main__":
    main()
