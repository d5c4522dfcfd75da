"""One fleet's processes, for both launchers (``mstc up`` and ``mstc tree-fleet``): spawning
children into the run directory, the signals that stop the launcher, the kill schedule,
fleet.json (what ``mstc kill``, ``mstc down`` and ``mstc monitor`` read), the ordered
shutdown and the optional recording of the mission.

A launcher owns one Supervisor; what it supervises (coverage of a grid, steps of a tree) is
its own business. Children are stopped agents first, then the world processes (simhw, the
radio), then the router, each with SIGTERM and a SIGKILL after a grace period, whatever ended
the mission (also exceptions): agents that outlive the world would report it lost.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import signal
from collections.abc import Awaitable, Callable, Iterator
from pathlib import Path
from typing import TypeVar

from bus.config import ConnectionSettings
from deploy.fleet import (
    LAUNCHER,
    SHUTDOWN_ORDER,
    Child,
    FleetInfo,
    ProcessRecord,
    RunDir,
    start_ticks,
    stop_children,
    wait_ready,
)
from deploy.monitor.types import RecorderLink
from deploy.settings import KillOrder

T = TypeVar("T")
STOP_GRACE_S = 5.0


class KillSchedule:
    """Kill orders not carried out yet; ``due`` hands out those whose moment has come."""

    def __init__(self, orders: tuple[KillOrder, ...] | list[KillOrder]) -> None:
        self.pending = list(orders)

    def due(self, *, elapsed: float | None = None, coverage: float | None = None,
            step: int | None = None) -> list[KillOrder]:
        """Orders due at ``elapsed`` mission seconds, ``coverage`` percent or ``step``
        completed steps (whichever the mission measures), removed from the schedule."""
        ready = [o for o in self.pending if o.is_due(elapsed, coverage, step)]
        self.pending = [o for o in self.pending if o not in ready]
        return ready

    def due_earliest_step(self, step: int) -> list[KillOrder]:
        """Like ``due(step=step)``, but only the orders of the earliest step among those due;
        the later ones stay in the schedule (tree missions apply deaths one step at a time)."""
        ready = [o for o in self.pending if o.is_due(None, None, step)]
        first = min((o.step for o in ready if o.step is not None), default=None)
        taken = [o for o in ready if o.step == first]
        self.pending = [o for o in self.pending if o not in taken]
        return taken

    def take(self, wanted: Callable[[KillOrder], bool]) -> list[KillOrder]:
        """The orders ``wanted`` picks, removed from the schedule whatever their moment."""
        taken = [o for o in self.pending if wanted(o)]
        self.pending = [o for o in self.pending if o not in taken]
        return taken

    def waits_on_coverage(self, coverage: float) -> bool:
        """True if a coverage-triggered order has become due (without taking it)."""
        return any(o.percent is not None and coverage >= o.percent for o in self.pending)


class Supervisor:
    """Starts, signals, records in fleet.json and stops the processes of one fleet."""

    def __init__(self, run_dir: RunDir) -> None:
        self.run_dir = run_dir
        self.children: list[Child] = []
        self.stop = asyncio.Event()
        self.wake = asyncio.Event()  # set with ``stop``: a launcher's wait ends at once
        self.stop_signal: int | None = None

    # --- processes -------------------------------------------------------------------------

    def spawn(self, name: str, role: str, argv: list[str], robot: int | None = None) -> Child:
        child = Child(name, role, argv, self.run_dir.log_path(name), robot)
        self.run_dir.write_pid(child.record)
        self.children.append(child)
        return child

    async def wait_ready(self, child: Child, mark: str, timeout: float) -> None:
        await wait_ready(child, mark, timeout, self.stop)

    @property
    def agents(self) -> list[Child]:
        return [c for c in self.children if c.role == "agent"]

    def agent(self, robot: int) -> Child:
        return next(c for c in self.agents if c.robot == robot)

    def kill_agent(self, robot: int) -> Child:
        """SIGKILL robot ``robot``'s agent (a fail-stop robot), marked as expected."""
        child = self.agent(robot)
        child.expected_exit = True
        child.signal(signal.SIGKILL)
        return child

    def write_fleet(self, info: FleetInfo) -> None:
        """fleet.json with the launcher and every child so far (``info.processes`` ignored)."""
        me = ProcessRecord(name=LAUNCHER, role=LAUNCHER, pid=os.getpid(),
                           started=start_ticks(os.getpid()))
        self.run_dir.write_pid(me)
        self.run_dir.write_fleet(FleetInfo(**{
            **info.to_fields(), "processes": (me, *(c.record for c in self.children))}))

    def shutdown(self) -> None:
        """Stop every child in SHUTDOWN_ORDER (SIGTERM, then SIGKILL); remove the PID files."""
        for rank in sorted(set(SHUTDOWN_ORDER.values())):
            stop_children([c for c in self.children
                           if SHUTDOWN_ORDER.get(c.role, 0) == rank], STOP_GRACE_S)
        for child in self.children:
            self.run_dir.remove_pid(child.name)
        self.run_dir.remove_pid(LAUNCHER)

    # --- signals ---------------------------------------------------------------------------

    @property
    def stopped_by(self) -> str | None:
        """The name of the signal that asked the launcher to stop, if one did."""
        return None if self.stop_signal is None else signal.Signals(self.stop_signal).name

    def _on_signal(self, sig: int) -> None:
        self.stop_signal = sig
        self.stop.set()
        self.wake.set()

    @contextlib.contextmanager
    def signals_stop(self) -> Iterator[None]:
        """While inside, SIGINT, SIGTERM and SIGHUP set ``stop`` instead of ending us.

        SIGHUP too: closing the terminal must not orphan the children, which run in their own
        process sessions and so never see the terminal's hang-up themselves."""
        loop = asyncio.get_running_loop()
        handled: list[int] = []
        for sig in (int(signal.SIGINT), int(signal.SIGTERM), int(signal.SIGHUP)):
            with contextlib.suppress(NotImplementedError, RuntimeError):
                loop.add_signal_handler(sig, self._on_signal, sig)
                handled.append(sig)
        try:
            yield
        finally:
            for sig in handled:
                loop.remove_signal_handler(sig)


def run_recorded(main: Awaitable[T], connection: ConnectionSettings, record: Path | None,
                 source: str, record_mcap: Path | None = None,
                 link: RecorderLink | None = None) -> T:
    """Run a launcher's coroutine to its end, with every message of its mission recorded
    to ``record`` (JSON Lines, for mstc replay and mstc report) and/or ``record_mcap`` (MCAP,
    docs/robotics.md) when given; ``source`` (the command) goes into the recording's header.
    ``link`` tells the launcher when the recorder listens and what it has written (a launcher
    whose messages no cache can give back waits for both)."""
    if record is None and record_mcap is None:
        return asyncio.run(_awaited(main))
    from deploy.monitor.app import recorded  # the recorder pulls in the rich view

    return asyncio.run(recorded(main, connection, record, source, record_mcap, link))


async def _awaited(main: Awaitable[T]) -> T:
    return await main
