"""``mstc foxglove``: serve a mission live to Foxglove (or Lichtblick) over the Foxglove
WebSocket protocol: coverage grid, robots, tree, events and the map (docs/robotics.md).
Needs the ``robotics`` extra.

Exit codes: 0 when stopped (Ctrl-C, --duration, or the mission settled with
--exit-when-done); 2 for usage or connection mistakes.
"""

from __future__ import annotations

import argparse
import asyncio
import sys

from bus.config import add_connection_arguments, settings_from_args
from bus.errors import BusError
from deploy.errors import UsageError
from deploy.viewers import add_watch_arguments, run_viewer, stop_on_signals


def _port(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a port number: {text!r}") from None
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"a port is 0 to 65535, got {value}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--port", type=_port, default=8765,
                        help="WebSocket port (default %(default)s; 0: any free port)")
    parser.add_argument("--host", default="127.0.0.1",
                        help="address to serve on (default %(default)s: this machine only)")
    add_watch_arguments(parser, "serve")
    add_connection_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from deploy.cmd_monitor import follow_run_dir
    from deploy.robotics import require_extra

    require_extra()
    from deploy.monitor.app import Watcher, until_connected, watch_live
    from deploy.robotics.bridge import FoxgloveScreen

    try:
        # a viewer's bridge only watches: it logs in as observer unless told otherwise
        settings = follow_run_dir(args, settings_from_args(args, default_role="observer"))
    except BusError as error:
        raise UsageError(str(error)) from error
    try:
        screen = FoxgloveScreen(settings.mission, args.host, args.port)
    except RuntimeError as error:  # the SDK's error for a port in use or a bad address
        raise UsageError(f"cannot serve on {args.host}:{args.port}: {error}") from error
    print(f"serving mission {settings.mission} on ws://{args.host}:{screen.port} "
          f"(Foxglove: Open connection, Foxglove WebSocket)", file=sys.stderr, flush=True)
    watcher = Watcher(screen)

    async def main() -> None:
        stop = asyncio.Event()
        stop_on_signals(stop, lambda: watcher.connected)
        try:
            async with asyncio.TaskGroup() as group:
                group.create_task(until_connected(lambda: watcher.connected, settings,
                                                  args.connect_timeout,
                                                  say=_say))
                await watch_live(settings, watcher, stop=stop, duration=args.duration,
                                 until_settled=args.exit_when_done,
                                 world_period=args.world_period)
        except* (BusError, UsageError) as failed:
            raise failed.exceptions[0] from None

    try:
        return run_viewer(main())
    finally:
        screen.stop()


def _say(text: str) -> None:
    print(f"mstc foxglove: {text}", file=sys.stderr, flush=True)
