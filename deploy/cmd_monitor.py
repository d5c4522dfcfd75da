"""``mstc monitor``: watch a mission live from the wire (rich view, or one line per event).

Exit codes: 0 when stopped (Ctrl-C, --duration, or the mission settled with
--exit-when-done); 2 for usage or connection mistakes.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import signal
import sys
from dataclasses import replace
from pathlib import Path

from bus.config import ConnectionSettings, add_connection_arguments, settings_from_args
from bus.errors import BusError
from deploy.errors import UsageError
from deploy.viewers import add_watch_arguments


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--plain", action="store_true",
                        help="one line per event instead of the live view (also when stdout "
                             "is not a terminal)")
    parser.add_argument("--record", type=Path, default=None, metavar="FILE",
                        help="write every message to FILE as JSON Lines (see docs/protocol.md)")
    add_watch_arguments(parser, "watch")
    add_connection_arguments(parser)


def follow_run_dir(args: argparse.Namespace,
                    settings: ConnectionSettings) -> ConnectionSettings:
    """Point the monitor at a fleet started by `mstc up` or `mstc tree-fleet` (its mission
    name is unique per run). An explicit --mission (or MSTC_MISSION) wins; without a run
    directory the settings stay."""
    from bus.config import DEFAULT_MISSION, ENV_MISSION
    from deploy.errors import FleetError
    from deploy.fleet import RunDir, latest_run_dir
    from deploy.security import attach

    explicit_mission = args.mission != DEFAULT_MISSION or ENV_MISSION in os.environ
    if args.run_dir is None and explicit_mission:
        return settings
    try:
        run_dir = args.run_dir if args.run_dir is not None else latest_run_dir()
        info = RunDir(run_dir).read_fleet()
    except FleetError as error:
        if args.run_dir is not None:
            raise UsageError(str(error)) from error
        return settings
    creds = attach(settings.credentials, Path(run_dir), info)
    followed = replace(settings, mission=settings.mission if explicit_mission else info.mission,
                       connect=settings.connect or (info.endpoint,), credentials=creds)
    print(f"watching mission {followed.mission} of {run_dir} via {followed.connect[0]}",
          file=sys.stderr)
    return followed


def run(args: argparse.Namespace) -> int:
    from deploy.monitor.app import (
        PlainScreen,
        RichScreen,
        Screen,
        Watcher,
        until_connected,
        watch_live,
    )

    try:
        # a monitor only watches: it logs in as observer unless told otherwise
        settings = follow_run_dir(args, settings_from_args(args, default_role="observer"))
    except BusError as error:
        raise UsageError(str(error)) from error
    if args.record is not None and not args.record.parent.is_dir():
        raise UsageError(f"--record {args.record}: directory {args.record.parent} does not exist")
    screen: Screen = PlainScreen() if args.plain or not sys.stdout.isatty() else RichScreen()
    watcher = Watcher(screen)

    async def main() -> None:
        stop = asyncio.Event()
        loop = asyncio.get_running_loop()
        task = asyncio.current_task()

        def on_signal() -> None:
            # Still waiting for the router: nothing to show or flush, just give up.
            if not watcher.connected and task is not None:
                task.cancel()
            stop.set()

        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError, RuntimeError):
                loop.add_signal_handler(sig, on_signal)
        limit = min(args.connect_timeout, args.duration or args.connect_timeout)
        try:
            async with asyncio.TaskGroup() as group:
                group.create_task(until_connected(lambda: watcher.connected, settings, limit,
                                                  say=_say))
                if args.duration is not None:
                    group.create_task(_stop_after(stop, args.duration))
                await watch_live(settings, watcher, stop=stop,
                                 until_settled=args.exit_when_done,
                                 world_period=args.world_period, record=args.record)
                stop.set()  # ends the duration timer once the watch is over
        except* (BusError, UsageError) as failed:
            raise failed.exceptions[0] from None

    try:
        asyncio.run(main())
    except BusError as error:
        raise UsageError(str(error)) from error
    except asyncio.CancelledError:
        return 130
    return 0


def _say(text: str) -> None:
    print(f"mstc monitor: {text}", file=sys.stderr, flush=True)


async def _stop_after(stop: asyncio.Event, seconds: float) -> None:
    """--duration from the command's start, so that waiting for the router counts too."""
    with contextlib.suppress(TimeoutError):
        await asyncio.wait_for(stop.wait(), seconds)
    stop.set()
