"""``mstc down``: stop the fleet of a run directory (default: the most recent one).

The launcher (``mstc up`` or ``mstc tree-fleet``) is asked first with SIGTERM, so it stops
its children in order and prints its summary; whatever is still running after --timeout (for
example because the launcher itself was SIGKILLed) gets SIGTERM, then SIGKILL. PID files carry
each process's start time, so a pid reused by an unrelated process is never signalled."""

from __future__ import annotations

import argparse
import signal
from pathlib import Path

from deploy.fleet import (
    LAUNCHER,
    SHUTDOWN_ORDER,
    ProcessRecord,
    RunDir,
    latest_run_dir,
    send_signal,
    wait_gone,
)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--run-dir", type=Path, default=None, metavar="DIR",
                        help="the fleet's run directory (default: the most recent under runs/)")
    parser.add_argument("--timeout", type=float, default=10.0, metavar="S",
                        help="seconds to wait for a clean stop before SIGKILL (default 10)")


def _stop(records: list[ProcessRecord], timeout: float) -> list[ProcessRecord]:
    """SIGTERM, wait, SIGKILL; return the processes that needed SIGKILL."""
    signalled = [r for r in records if send_signal(r, signal.SIGTERM)]
    stubborn = wait_gone(signalled, timeout)
    for record in stubborn:
        send_signal(record, signal.SIGKILL)
    wait_gone(stubborn, 2.0)
    return stubborn


def run(args: argparse.Namespace) -> int:
    run_dir = RunDir(args.run_dir or latest_run_dir())
    info = run_dir.read_fleet()
    launcher = [p for p in info.processes if p.role == LAUNCHER]
    others = [p for p in info.processes if p.role != LAUNCHER]
    running = [p for p in info.processes if send_signal(p, 0)]
    if not running:
        print(f"mstc down: fleet {info.mission} in {run_dir.path} is not running")
        return 0
    killed = _stop(launcher, args.timeout)
    # Children outlive a launcher that was SIGKILLed: stop them in the launcher's order.
    for rank in sorted(set(SHUTDOWN_ORDER.values())):
        killed += _stop([p for p in others if SHUTDOWN_ORDER.get(p.role, 0) == rank],
                        args.timeout)
    note = f" ({len(killed)} needed SIGKILL: {[p.name for p in killed]})" if killed else ""
    print(f"mstc down: stopped fleet {info.mission} ({len(running)} processes){note}")
    return 0
