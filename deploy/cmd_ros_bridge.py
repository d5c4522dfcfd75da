"""``mstc ros-bridge``: a mission's map, robot poses and paths as ROS 2 topics on Zenoh, in
rmw_zenoh's format (docs/robotics.md). Needs the ``robotics`` extra; no ROS installation.

Exit codes: 0 when stopped (Ctrl-C, --duration, or the mission settled with
--exit-when-done); 2 for usage or connection mistakes.
"""

from __future__ import annotations

import argparse
import asyncio
import os
import sys
from dataclasses import replace

from bus.config import add_connection_arguments, open_session_async, settings_from_args
from bus.errors import BusError
from deploy.errors import UsageError
from deploy.viewers import add_watch_arguments, run_viewer, stop_on_signals


def _domain(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a ROS domain id: {text!r}") from None
    if not 0 <= value <= 232:
        raise argparse.ArgumentTypeError(f"a ROS domain id is 0 to 232, got {value}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--domain", type=_domain,
                        default=_domain(os.environ.get("ROS_DOMAIN_ID", "0") or "0"),
                        help="ROS domain id (default $ROS_DOMAIN_ID or 0)")
    parser.add_argument("--ros-connect", action="append", metavar="ENDPOINT", default=None,
                        help="publish the ROS topics through this Zenoh router (e.g. "
                             "rmw_zenohd's tcp/localhost:7447; default: the mission's)")
    add_watch_arguments(parser, "bridge")
    add_connection_arguments(parser)


def run(args: argparse.Namespace) -> int:
    from deploy.cmd_monitor import follow_run_dir
    from deploy.robotics import require_extra

    require_extra()
    from deploy.monitor.app import Watcher, until_connected, watch_live
    from deploy.robotics.ros_bridge import RosScreen

    try:
        # it watches the mission as observer; ROS topics live outside the mission's keys,
        # which a secured mission router admits nobody to write
        settings = follow_run_dir(args, settings_from_args(args, default_role="observer"))
    except BusError as error:
        raise UsageError(str(error)) from error
    if settings.secure and not args.ros_connect:
        raise UsageError("the mission's router admits no ROS topics (docs/security.md): give "
                         "--ros-connect ENDPOINT of a ROS router (rmw_zenohd), or run the "
                         "fleet with --insecure")
    ros_settings = settings if not args.ros_connect else \
        replace(settings, connect=tuple(args.ros_connect), listen=(), credentials=None,
                role=None)

    async def main() -> None:
        stop = asyncio.Event()
        connected = False
        stop_on_signals(stop, lambda: connected)
        watchers: list[Watcher] = []
        try:
            async with asyncio.TaskGroup() as group:
                group.create_task(until_connected(
                    lambda: bool(watchers) and watchers[0].connected, settings,
                    args.connect_timeout, say=_say))
                async with open_session_async(ros_settings) as session:
                    screen = RosScreen(session, args.domain)
                    connected = True
                    _say(f"bridging mission {settings.mission} to ROS 2 domain "
                         f"{args.domain} (node /{screen.node.name}, zid {screen.node.zid})")
                    watchers.append(Watcher(screen))
                    try:
                        await watch_live(settings, watchers[0], stop=stop,
                                         duration=args.duration,
                                         until_settled=args.exit_when_done,
                                         world_period=args.world_period)
                    finally:
                        screen.stop()
        except* (BusError, UsageError) as failed:
            raise failed.exceptions[0] from None

    return run_viewer(main())


def _say(text: str) -> None:
    print(f"mstc ros-bridge: {text}", file=sys.stderr, flush=True)
