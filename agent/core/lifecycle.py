"""The process life cycle every agent shares, whatever algorithm drives its body.

One asyncio TaskGroup holds the mission beside the liveness service (token, heartbeats,
failure detector), the announcer (re-published state, answers to state queries) and watchers
that end the group with a specific exception: own death notice (FencedError) and
SIGTERM/SIGINT (LeaveRequested), plus whatever a subclass adds. How the group ends decides
what the others are told (status, event) and the exit code.

A subclass wires itself to the bus in ``_wire`` (setting ``liveness`` and ``announcer``,
made by ``_make_liveness`` and ``_make_announcer`` from the one AgentConfig), runs its
mission in ``_mission`` and says how it reports its status in ``_status``.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import signal
import sys
from abc import ABC, abstractmethod
from collections.abc import Callable, Coroutine
from typing import Any, ClassVar

from agent.core.announcer import StateAnnouncer, holds_deaths
from agent.core.config import AgentConfig
from agent.core.errors import AgentError, FencedError, LeaveRequested
from bus import keys
from bus.bridge import Bus
from bus.config import DEFAULT_LEASE_MS, ConnectionSettings
from bus.errors import BusError
from bus.faults import MessageFaults
from bus.liveness import HeartbeatInfo, LivelinessService
from bus.messages import AgentState, DeathNotice, EventKind, Heartbeat, RobotEvent

# Time for the last status and event to leave before the session closes.
LEAVE_FLUSH_S = 0.1


class AgentLife(ABC):
    """One robot process. ``await agent.run(settings)`` returns the process exit code."""

    # The exception that decides how the process ends, most decisive first.
    END_PRIORITY: ClassVar[tuple[type[BaseException], ...]] = (
        FencedError, LeaveRequested, AgentError)

    bus: Bus
    liveness: LivelinessService
    announcer: StateAnnouncer

    def __init__(self, config: AgentConfig) -> None:
        self.config = config
        self.robot = config.robot
        self.incarnation = config.incarnation
        self.stop = asyncio.Event()
        self.error = ""
        self.lease = DEFAULT_LEASE_MS / 1000  # the session's (run() sets it): weighs stalls

    def _make_liveness(self, bus: Bus, on_death: Callable[[DeathNotice], None],
                       info: Callable[[], HeartbeatInfo] = HeartbeatInfo,
                       on_beat: Callable[[Heartbeat], None] | None = None) -> LivelinessService:
        c = self.config
        return LivelinessService(bus, self.robot, self.incarnation,
                                 heartbeat_period=c.heartbeat_period, timeout=c.dead_after,
                                 token_grace=c.token_grace, lease=self.lease,
                                 info=info, on_death=on_death, on_beat=on_beat)

    def _make_announcer(self, bus: Bus,
                        state: Callable[[], AgentState] | None = None) -> StateAnnouncer:
        return StateAnnouncer(bus, keys.state(bus.mission, self.robot),
                              self.config.announce_period, state,
                              death_holder=lambda: holds_deaths(
                                  self.robot, self.liveness.detector.alive()))

    def _event(self, kind: EventKind, subject: int | None = None, detail: str = "") -> None:
        self.bus.publish(keys.events(self.bus.mission, self.robot),
                         RobotEvent(self.robot, self.incarnation, kind, subject, detail))

    @abstractmethod
    def _wire(self, bus: Bus) -> None: ...

    @abstractmethod
    async def _mission(self) -> None: ...

    @abstractmethod
    def _status(self, state: str, message: str = "") -> None: ...

    def _watchers(self) -> list[Coroutine[Any, Any, None]]:
        """Background tasks that end the group by raising (subclasses may add)."""
        return [self._watch_fence(), self._watch_stop()]

    def _ending_agent_error(self, error: AgentError) -> None:
        """Hook: extra reports before a stop on an AgentError."""
        return None

    async def _watch_fence(self) -> None:
        await self.liveness.fenced.wait()
        raise FencedError(f"robot {self.robot} incarnation {self.incarnation} was declared "
                          "dead; stopping")

    async def _watch_stop(self) -> None:
        await self.stop.wait()
        raise LeaveRequested()

    async def _run_group(self) -> None:
        async with asyncio.TaskGroup() as group:
            background = [group.create_task(self.liveness.run()),
                          group.create_task(self.announcer.run()),
                          *(group.create_task(w) for w in self._watchers())]
            await self._mission()
            for task in background:
                task.cancel()

    async def run(self, settings: ConnectionSettings) -> int:
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGTERM, signal.SIGINT):
            with contextlib.suppress(NotImplementedError, RuntimeError):
                loop.add_signal_handler(sig, self.stop.set)
        # Message faults for robustness trials (bus.faults; MSTC_FAULTS, unset in production)
        self.lease = settings.lease_ms / 1000
        async with Bus.connect(settings, faults=MessageFaults.from_env()) as bus:
            self.bus = bus
            self._wire(bus)
            try:
                await self._run_group()
            except BaseExceptionGroup as group:
                return await self._ending(main_error(group, self.END_PRIORITY))
            self.liveness.leave()
            await asyncio.sleep(LEAVE_FLUSH_S)
        return 0

    async def _ending(self, error: BaseException) -> int:
        """Tell the others how this life ends; return the exit code."""
        self.error = str(error) or type(error).__name__
        if isinstance(error, LeaveRequested):
            self._status("left", "SIGTERM/SIGINT")
            self._event("leaving", detail="asked to stop")
            self.liveness.leave()
            code = 0
        elif isinstance(error, FencedError):
            self._status("fenced", str(error))
            self._event("fenced", detail=str(error))
            code = error.exit_code
        elif isinstance(error, AgentError):
            self._ending_agent_error(error)
            self._status("stopped", str(error))
            self._event("stopped", detail=str(error))
            self.liveness.leave()
            code = error.exit_code
        else:
            raise error
        await asyncio.sleep(LEAVE_FLUSH_S)
        return code


def main_error(group: BaseExceptionGroup[BaseException],
               priority: tuple[type[BaseException], ...]) -> BaseException:
    """The leaf exception of ``group`` of the first kind in ``priority`` (else the first)."""
    flat = _leaves(group)
    for kind in priority:
        for exc in flat:
            if isinstance(exc, kind):
                return exc
    return flat[0]


def _leaves(exc: BaseException) -> list[BaseException]:
    if isinstance(exc, BaseExceptionGroup):
        return [leaf for inner in exc.exceptions for leaf in _leaves(inner)]
    return [exc]


def run_agent(agent: AgentLife, settings: ConnectionSettings) -> int:
    """Run ``agent`` to its end in a fresh event loop; bus mistakes are one line (exit 2)."""
    logging.basicConfig(level=logging.WARNING,
                        format=f"agent {agent.robot} %(levelname)s %(message)s")
    try:
        code = asyncio.run(agent.run(settings))
    except BusError as error:
        print(f"mstc agent: error: {error}", file=sys.stderr)
        return 2
    if code != 0:
        # A fenced robot did what it must (it was declared dead, so it stopped): not an error.
        word = "fenced" if code == FencedError.exit_code else "error"
        print(f"mstc agent {agent.robot}: {word}: {agent.error}", file=sys.stderr)
    return code
