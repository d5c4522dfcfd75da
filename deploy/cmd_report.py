"""``mstc report FILE``: figures and invariant checks of a recorded mission.

Exit codes: 0 every invariant held (or could not be checked), 1 an invariant failed,
2 the file is unusable.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from deploy.cli import UsageError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", type=Path, metavar="FILE", help="a recording (JSON Lines)")
    parser.add_argument("--png", type=Path, default=None, metavar="OUT",
                        help="also draw the map, trees, walks and coverage curve to OUT")
    parser.add_argument("--json", action="store_true",
                        help="print the report as JSON (schema mstc-report, version 1)")


def run(args: argparse.Namespace) -> int:
    try:
        return _run(args)
    except UsageError as error:
        # Caught here too: under "python -m deploy.cli" the dispatcher's UsageError is another
        # class object than the one deploy.cli exports to us.
        print(f"mstc report: error: {error}", file=sys.stderr)
        return 2


def _run(args: argparse.Namespace) -> int:
    from deploy.monitor.recorder import read_recording
    from deploy.monitor.report import build_report, format_report, replay_model

    png = None
    if args.png is not None:
        from deploy.figure_path import figure_path

        png = figure_path(args.png, "--png")
    recording = read_recording(args.file)
    for error in recording.errors:
        print(f"{args.file}:{error.line}: skipped: {error.reason}", file=sys.stderr)
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
