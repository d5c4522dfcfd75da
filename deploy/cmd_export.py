"""``mstc export RECORDING --mcap OUT [--rosbag2 DIR]``: a recording as files robotics tools
open (Foxglove / Lichtblick read MCAP, ``ros2 bag`` and RViz read rosbag2); see
docs/robotics.md. Needs the ``robotics`` extra.

Exit codes: 0 written, 2 the recording or an output is unusable.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from bus.argtypes import positive
from deploy.errors import UsageError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("file", type=Path, metavar="RECORDING",
                        help="a recording (JSON Lines, from --record)")
    parser.add_argument("--mcap", type=Path, default=None, metavar="OUT",
                        help="write an MCAP file (Foxglove schemas; overwritten if present)")
    parser.add_argument("--rosbag2", type=Path, default=None, metavar="DIR",
                        help="write a rosbag2 directory (ROS 2 types; DIR must not exist)")
    parser.add_argument("--period", type=positive, default=0.1, metavar="S",
                        help="sample the map, coverage, robots and tree every S seconds of "
                             "recording time (default %(default)s)")


def run(args: argparse.Namespace) -> int:
    if args.mcap is None and args.rosbag2 is None:
        raise UsageError("nothing to write: give --mcap OUT and/or --rosbag2 DIR")
    for path in (args.mcap, args.rosbag2):
        if path is not None and not path.absolute().parent.is_dir():
            raise UsageError(f"{path}: directory {path.absolute().parent} does not exist")
    from deploy.monitor.recorder import read_recording
    from deploy.robotics import require_extra

    require_extra()
    from deploy.robotics.export import export

    recording = read_recording(args.file)
    for error in recording.errors:
        print(f"{args.file}:{error.line}: skipped: {error.reason}", file=sys.stderr)
    counts = export(recording, mcap=args.mcap, rosbag2=args.rosbag2, period=args.period)
    written = ", ".join(str(p) for p in (args.mcap, args.rosbag2) if p is not None)
    sent = ", ".join(f"{n} {name}" for name, n in counts.sent.items())
    print(f"wrote {written}: {counts.records} wire messages, {sent}")
    return 0
