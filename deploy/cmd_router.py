"""``mstc router``: a Zenoh router in a plain Python process (no plugins; use zenohd for
REST or storages). Listens on loopback by default; connect routers of other hosts with
--connect. Prints one ``ready`` line when listening; SIGTERM/SIGINT close it cleanly."""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys

from bus.config import DEFAULT_ENDPOINT, add_connection_arguments, settings_from_args
from bus.errors import BusError, ConfigError
from bus.router import READY_MARK, StopSignals, run_router


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_connection_arguments(parser)
    parser.add_argument("--exit-with-parent", action="store_true",
                        help="stop when the process that started this router dies "
                             "(used by tests and launchers so no router is orphaned)")
    parser.set_defaults(mode="router")
    parser.epilog = f"Default listen endpoint: {DEFAULT_ENDPOINT}."


def run(args: argparse.Namespace) -> int:
    try:
        settings = settings_from_args(args)
        if settings.mode != "router":
            settings = dataclasses.replace(settings, mode="router")
        if not settings.listen:
            settings = dataclasses.replace(settings, listen=(DEFAULT_ENDPOINT,))
    except BusError as error:
        print(f"mstc router: error: {error}", file=sys.stderr)
        return 2
    parent = os.getppid() if args.exit_with_parent else None
    stop_signals = StopSignals()
    stop_signals.install()
    try:
        run_router(settings, stop_signals, ready=lambda: print(
            f"{READY_MARK}, listening on {', '.join(settings.listen)}", flush=True),
            parent=parent)
    except ConfigError as error:  # a mistake in the settings, found while applying them
        print(f"mstc router: error: {error}", file=sys.stderr)
        return 2
    except BusError as error:
        print(f"mstc router: error: {error}", file=sys.stderr)
        return 1
    # The session is closed (or given up on after bus.router.CLOSE_TIMEOUT_S): leave without
    # waiting for Zenoh's runtime threads at interpreter exit, which can hang a router process.
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(0)
