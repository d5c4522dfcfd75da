"""``mstc monitor``: watch a mission live from the wire (rich view, or one line per event).

Exit codes: 0 when stopped (Ctrl-C, --duration, or the mission settled with
--exit-when-done); 2 for usage or connection mistakes.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import os
import sys
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

from bus.config import ConnectionSettings, add_connection_arguments, settings_from_args
from bus.errors import BusError
from deploy.errors import FleetError, UsageError
from deploy.viewers import add_watch_arguments, stop_on_signals

if TYPE_CHECKING:
    from deploy.fleet import FleetInfo
    from deploy.monitor.app import Screen, Watcher
    from deploy.monitor.discovery import LiveRun

POLL_S = 0.5  # how often run directories are looked at again


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
    """Point a viewer at a fleet started by `mstc up` or `mstc tree-fleet` (its mission
    name is unique per run): --run-dir, else the live run, else the latest. An explicit
    --mission (or MSTC_MISSION) wins; without a run directory the settings stay."""
    from deploy.errors import FleetError
    from deploy.fleet import RunDir, latest_run_dir

    if args.run_dir is None and _explicit_mission(args):
        return settings
    try:
        if args.run_dir is not None:
            run_dir = args.run_dir
        else:  # the run whose fleet is running, else the latest
            from deploy.monitor.discovery import live_runs

            live = [r.run_dir for r in live_runs() if r.run_dir is not None]
            run_dir = live[0] if live else latest_run_dir()
        info = RunDir(run_dir).read_fleet()
    except FleetError as error:
        if args.run_dir is not None:
            raise UsageError(str(error)) from error
        return settings
    return _attached(args, settings, Path(run_dir), info)


def _explicit_mission(args: argparse.Namespace) -> bool:
    from bus.config import DEFAULT_MISSION, ENV_MISSION

    return bool(args.mission != DEFAULT_MISSION or ENV_MISSION in os.environ)


def _attached(args: argparse.Namespace, settings: ConnectionSettings, run_dir: Path,
              info: FleetInfo) -> ConnectionSettings:
    from deploy.security import attach

    creds = attach(settings.credentials, run_dir, info)
    followed = replace(settings, mission=settings.mission if _explicit_mission(args)
                       else info.mission, connect=settings.connect or (info.endpoint,),
                       credentials=creds)
    _say(f"watching mission {followed.mission} of {run_dir} via {followed.connect[0]}")
    return followed


class MissionChooser:
    """Which mission to watch, and when to move to a newer run (deploy.monitor.discovery):
    pinned by --run-dir or --mission, else the live run (a run directory whose launcher
    runs, or a mission on the router), waited for when there is none yet."""

    def __init__(self, args: argparse.Namespace, base: ConnectionSettings) -> None:
        self.args, self.base = args, base
        self.pinned = args.run_dir is not None or _explicit_mission(args)
        self.current: LiveRun | None = None
        self.next: ConnectionSettings | None = None

    async def first(self, stop: asyncio.Event,
                    group: asyncio.TaskGroup) -> ConnectionSettings | None:
        """The settings of the mission to watch; None if stopped first; FleetError when no
        mission turned up within --connect-timeout."""
        from deploy.fleet import RunDir
        from deploy.monitor.discovery import choose, ended_run, live_runs

        if self.pinned:
            return follow_run_dir(self.args, self.base)
        heard: list[LiveRun] = []
        limit = self.args.connect_timeout
        loop = asyncio.get_running_loop()
        deadline, told = loop.time() + limit, False
        asking = group.create_task(self._ask_router(heard))
        try:
            while not stop.is_set():
                run, lines = choose(live_runs() or list(heard))
                if run is not None:
                    for line in lines:
                        _say(line)
                    self.current = run
                    if run.run_dir is None:
                        _say(f"watching {run.describe()} via {self.base.endpoints[0]}")
                        return replace(self.base, mission=run.mission)
                    return _attached(self.args, self.base, run.run_dir,
                                     RunDir(run.run_dir).read_fleet())
                if not told:
                    ended = ended_run()
                    was = "" if ended is None else f" (the latest, {ended}, has ended)"
                    _say(f"no live run under runs/{was}; waiting up to {limit:g} s for a "
                         f"fleet to start (mstc up) or for robots on the router at "
                         f"{', '.join(self.base.endpoints)}")
                    told = True
                if loop.time() >= deadline:
                    raise FleetError(
                        f"no live mission within {limit:g} s: no fleet running under "
                        f"runs/ and no robots on the router at "
                        f"{', '.join(self.base.endpoints)} (start one with mstc up, or "
                        f"name it with --run-dir or --mission; a router that enforces "
                        f"credentials also needs --credentials)")
                await asyncio.sleep(POLL_S)
            return None
        finally:
            asking.cancel()

    async def _ask_router(self, heard: list[LiveRun]) -> None:
        """Missions on the router, asked every second once a session opens (a router that
        refuses this observer never answers: the run directories still may)."""
        from bus.config import open_session_async
        from deploy.monitor.discovery import router_missions

        async with open_session_async(replace(self.base, mission="discovery")) as session:
            while True:
                heard[:] = await router_missions(session)
                await asyncio.sleep(1.0)

    async def follow(self, watcher: Watcher, stop: asyncio.Event,
                     this_run: asyncio.Event) -> None:
        """End ``this_run`` when the monitor stops, or when a newer run starts (of the same
        mission if one was named): ``next`` then holds its settings."""
        from deploy.fleet import RunDir
        from deploy.monitor.discovery import live_runs, newer_run

        while not stop.is_set():
            if watcher.new_run:  # the same mission again: its robots' new lives after the end
                self.next = replace(self.base, mission=watcher.mission) \
                    if self.current is None or self.current.run_dir is None else None
                if self.next is not None:
                    _say(f"mission {watcher.mission} runs again: following its new run")
                    break
            current = self.current
            if current is not None and current.run_dir is not None \
                    and self.args.run_dir is None:
                newer = newer_run(current, live_runs(), same_mission=self.pinned)
                if newer is not None and newer.run_dir is not None:
                    self.current = newer
                    _say(f"a new run started: following {newer.describe()}")
                    self.next = _attached(self.args, self.base, newer.run_dir,
                                          RunDir(newer.run_dir).read_fleet())
                    break
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(stop.wait(), POLL_S)
        this_run.set()


def run(args: argparse.Namespace) -> int:
    from deploy.monitor.app import PlainScreen, RichScreen

    try:
        # a monitor only watches: it logs in as observer unless told otherwise
        base = settings_from_args(args, default_role="observer")
    except BusError as error:
        raise UsageError(str(error)) from error
    if args.record is not None and not args.record.parent.is_dir():
        raise UsageError(f"--record {args.record}: directory {args.record.parent} does not exist")
    plain = args.plain or not sys.stdout.isatty()

    def screen() -> Screen:
        return PlainScreen() if plain else RichScreen()

    try:
        asyncio.run(_main(args, MissionChooser(args, base), screen))
    except BusError as error:
        raise UsageError(str(error)) from error
    except asyncio.CancelledError:
        return 130
    return 0


async def _main(args: argparse.Namespace, chooser: MissionChooser,
                screen: Callable[[], Screen]) -> None:
    from deploy.monitor.app import Watcher, until_connected, watch_live

    stop = asyncio.Event()
    watching: list[Watcher] = []
    stop_on_signals(stop, lambda: bool(watching) and watching[-1].connected)
    limit = min(args.connect_timeout, args.duration or args.connect_timeout)
    try:
        async with asyncio.TaskGroup() as group:
            if args.duration is not None:
                group.create_task(_stop_after(stop, args.duration))
            settings = await chooser.first(stop, group)
            while settings is not None and not stop.is_set():
                watcher = Watcher(screen())
                watcher.mission = settings.mission
                watching.append(watcher)
                this_run = asyncio.Event()
                # a recording is of one run: with --record the monitor stays on it
                follow = group.create_task(chooser.follow(watcher, stop, this_run)) \
                    if args.record is None else None
                connect = group.create_task(until_connected(
                    _connected(watcher), settings, limit, say=_say))
                try:
                    await watch_live(settings, watcher, stop=this_run if follow else stop,
                                     until_settled=args.exit_when_done,
                                     world_period=args.world_period, record=args.record)
                finally:
                    connect.cancel()
                    if follow is not None:
                        follow.cancel()
                if stop.is_set() or (args.exit_when_done and watcher.settled()) \
                        or chooser.next is None:
                    break
                settings, chooser.next = chooser.next, None
            stop.set()  # ends the duration timer once the watch is over
    except* (BusError, UsageError, FleetError) as failed:
        raise failed.exceptions[0] from None


def _connected(watcher: Watcher) -> Callable[[], bool]:
    return lambda: watcher.connected


def _say(text: str) -> None:
    print(f"mstc monitor: {text}", file=sys.stderr, flush=True)


async def _stop_after(stop: asyncio.Event, seconds: float) -> None:
    """--duration from the command's start, so that waiting for the router counts too."""
    with contextlib.suppress(TimeoutError):
        await asyncio.wait_for(stop.wait(), seconds)
    stop.set()
