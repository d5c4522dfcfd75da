"""``mstc replay FILE``: play a recording back through the monitor's live view."""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path


def _speed(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"speed must be >= 0, got {text!r}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", type=Path, metavar="FILE", help="a recording (JSON Lines)")
    parser.add_argument("--speed", type=_speed, default=1.0, metavar="X",
                        help="X times real time; 0 = as fast as possible (default 1)")
    parser.add_argument("--plain", action="store_true",
                        help="one line per event instead of the live view")


def run(args: argparse.Namespace) -> int:
    from deploy.monitor.app import PlainScreen, RichScreen, Screen, Watcher, replay
    from deploy.monitor.recorder import read_recording

    recording = read_recording(args.file)
    for error in recording.errors:
        print(f"{args.file}:{error.line}: skipped: {error.reason}", file=sys.stderr)
    screen: Screen = PlainScreen() if args.plain or not sys.stdout.isatty() else RichScreen()
    replay(recording, Watcher(screen), args.speed)
    return 0
