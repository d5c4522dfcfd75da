"""``mstc report FILE``: figures and invariant checks of a recorded mission.

A recording of ``mstc tree-fleet`` gets the launcher's own verdict instead: the robots'
reports against the lockstep run with the same deaths (deploy.monitor.tree_report).

Exit codes: 0 every invariant held or could not be checked (tree missions: the verdict is
"ok"), 1 an invariant failed (or the verdict is not "ok"), 2 the file is unusable.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", type=Path, metavar="FILE", help="a recording (JSON Lines)")
    parser.add_argument("--png", type=Path, default=None, metavar="OUT",
                        help="also draw the map, trees, walks and coverage curve to OUT")
    parser.add_argument("--json", action="store_true",
                        help="print the report as JSON (schema mstc-report, version 1)")


def run(args: argparse.Namespace) -> int:
    from deploy.monitor.recorder import read_recording
    from deploy.monitor.report import build_report, format_report, replay_model
    from deploy.monitor.tree_report import build_tree_report, tree_model

    png = None
    if args.png is not None:
        from deploy.figure_path import figure_path

        png = figure_path(args.png, "--png")
    recording = read_recording(args.file)
    for error in recording.errors:
        print(f"{args.file}:{error.line}: skipped: {error.reason}", file=sys.stderr)
    tree_mission = tree_model(recording)
    if tree_mission is not None:
        return _tree_report(build_tree_report(tree_mission), args.json)
    report = build_report(recording)
    if args.json:
        print(json.dumps(report.to_json(), indent=2, sort_keys=True))
    else:
        print(format_report(report))
    if png is not None:
        from deploy.monitor.report_png import write_png

        write_png(replay_model(recording.records)[0], report, png)
    failed = [inv for inv in report.invariants if inv.status == "failed"]
    for inv in failed:
        print(f"mstc report: invariant failed: {inv.name}: {inv.detail}", file=sys.stderr)
    return 1 if failed else 0


def _tree_report(summary: dict[str, object], as_json: bool) -> int:
    from deploy.tree_verdict import format_verdict

    print(json.dumps(summary, indent=2, sort_keys=True) if as_json else format_verdict(summary))
    if summary["verdict"] != "ok":
        print(f"mstc report: verdict: {summary['verdict']}", file=sys.stderr)
        return 1
    return 0
