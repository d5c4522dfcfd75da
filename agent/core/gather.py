"""The one gather of the agents with a simhw body: read where the body stands, announce it
(RobotStatus "gathering"), and wait until every robot has announced its start.

Nobody moves, plans or publishes a mission message before it holds every start (so a peer
listens before anything is said to it); ``_until`` is also the offline agents' wait for every
plan digest. Each wait ends with a GatherTimeoutError naming the robots still missing.
"""

from __future__ import annotations

import asyncio
import time
from abc import abstractmethod
from collections.abc import Callable

from agent.core.config import AgentConfig
from agent.core.errors import GatherTimeoutError
from agent.core.hw_link import HwLink
from agent.core.lifecycle import AgentLife


class BodyAgent(AgentLife):
    """An agent whose robot has a body in simhw: it starts where the body stands."""

    start: tuple[int, int] | None

    def __init__(self, config: AgentConfig) -> None:
        super().__init__(config)
        self.start = None
        self._t0 = time.monotonic()

    def now(self) -> float:
        """Seconds since this agent was made (the clock of its life-cycle lines)."""
        return time.monotonic() - self._t0

    def _say(self, text: str) -> None:
        """One life-cycle line on stdout (launchers and tests wait for them)."""
        print(f"agent {self.robot}: {text} [{self.now():.2f} s]", flush=True)

    @abstractmethod
    def _link(self) -> HwLink:
        """The body's command channel."""

    @abstractmethod
    def _missing_starts(self) -> list[int]:
        """Robots whose start is still unknown (and may still come)."""

    @abstractmethod
    async def _wait_news(self) -> None:
        """Until something is heard, or one announce period (pulling what may be lost)."""

    def _gathering(self) -> None:
        """Hook: the body's pose is known and the gather begins."""
        return None

    async def _gather_starts(self) -> tuple[int, int]:
        """This robot's start, once every robot has announced its own."""
        pose = await self._link().wait_for_pose(self.config.start_timeout)
        self.start = (int(pose[0]), int(pose[1]))
        self._gathering()
        self._say(f"body at {self.start}, gathering")
        self._status("gathering")
        await self._until(self._missing_starts, "announce their start")
        return self.start

    async def _until(self, missing: Callable[[], list[int]], what: str,
                     check: Callable[[], None] | None = None) -> None:
        """Wait until ``missing()`` is empty (running ``check`` on every news);
        GatherTimeoutError naming the robots still missing."""
        patience = self.config.start_timeout
        try:
            async with asyncio.timeout(patience):
                while missing():
                    if check is not None:
                        check()
                    await self._wait_news()
        except TimeoutError:
            raise GatherTimeoutError(
                f"robots {missing()} did not {what} within {patience:g} s "
                f"(mission {self.bus.mission!r}, {self.config.k} robots expected)") from None
