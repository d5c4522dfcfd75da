"""What the read-only viewers of a live mission (``mstc monitor``, ``mstc foxglove``,
``mstc ros-bridge``) share:
their watching options, their stop on a signal, and how a run ends as an exit code."""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import signal
from collections.abc import Callable, Coroutine
from pathlib import Path
from typing import Any

from bus.argtypes import positive
from bus.errors import BusError
from deploy.errors import UsageError

CONNECT_TIMEOUT_S = 30.0


def add_watch_arguments(parser: argparse.ArgumentParser, verb: str) -> None:
    """``--duration``, ``--connect-timeout``, ``--exit-when-done``, ``--world-period`` and
    ``--run-dir``; ``verb`` says what the viewer does with the fleet ("serve", "bridge")."""
    parser.add_argument("--duration", type=positive, default=None, metavar="S",
                        help="stop after S seconds (counted from the start, waiting for the "
                             "router included)")
    parser.add_argument("--connect-timeout", type=positive, default=CONNECT_TIMEOUT_S,
                        metavar="S", help="give up (exit 2) if no router answers within S "
                                          "seconds (default %(default)s)")
    parser.add_argument("--exit-when-done", action="store_true",
                        help="stop once the mission has a verdict and every robot is done, "
                             "dead or gone")
    parser.add_argument("--world-period", type=positive, default=2.0, metavar="S",
                        help="re-query the world and the robots' state every S seconds "
                             "(default %(default)s)")
    parser.add_argument("--run-dir", type=Path, default=None, metavar="DIR",
                        help=f"{verb} the fleet of this `mstc up` run directory (default, "
                             "when neither --mission nor MSTC_MISSION is given: the run "
                             "under runs/ whose fleet is running; mstc monitor waits for "
                             "one, or asks the router which missions are live)")


def stop_on_signals(stop: asyncio.Event, connected: Callable[[], bool]) -> None:
    """SIGINT/SIGTERM set ``stop``; before the first connection they cancel the run (there is
    nothing to close cleanly yet)."""
    loop = asyncio.get_running_loop()
    task = asyncio.current_task()

    def on_signal() -> None:
        if not connected() and task is not None:
            task.cancel()
        stop.set()

    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError):
            loop.add_signal_handler(sig, on_signal)


def run_viewer(main: Coroutine[Any, Any, None]) -> int:
    """Run a viewer's ``main``: 0 when it stopped, 130 when cancelled before connecting; bus
    mistakes become one-line usage errors."""
    try:
        asyncio.run(main)
    except BusError as error:
        raise UsageError(str(error)) from error
    except asyncio.CancelledError:
        return 130
    return 0
