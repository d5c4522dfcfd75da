"""The one gather of the agents with a simhw body: read where the body stands, announce it
(RobotStatus "gathering"), and agree with the others on who takes part (agent.core.roster):
every expected robot heard, known dead or absent past the boot timeout, and every live
participant proposing the same set.

Nobody moves, plans or publishes a mission message before the agreement (so a peer listens
before anything is said to it); ``_until`` is also the offline agents' wait for every plan
digest. Each wait ends with a GatherTimeoutError naming the robots still missing; a robot
left out of a set the others committed to stands down (StoodDownError, exit code 0).
"""

from __future__ import annotations

import asyncio
import time
from abc import abstractmethod
from collections.abc import Callable, Collection, Mapping, Sequence

from agent.core import roster as agreement
from agent.core.config import AgentConfig
from agent.core.errors import GatherTimeoutError, StoodDownError
from agent.core.hw_link import HwLink
from agent.core.lifecycle import AgentLife
from bus.messages import RobotStatus

# Seconds between two agreement decisions, per robot of the fleet (6 robots: 12 ms; 100:
# 0.2 s, where a decision over 100 rosters takes ~2 ms and statuses come 20 times a second).
DECIDE_SPACING_S = 0.002


class BodyAgent(AgentLife):
    """An agent whose robot has a body in simhw: it starts where the body stands."""

    start: tuple[int, int] | None

    def __init__(self, config: AgentConfig) -> None:
        super().__init__(config)
        self.start = None
        self.roster: agreement.Roster | None = None  # the agreed participants
        self.proposal: agreement.Roster | None = None
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
    def _peer_statuses(self) -> Mapping[int, RobotStatus]:
        """The newest status heard of each robot (this one's may be among them)."""

    @abstractmethod
    def _dead_robots(self) -> Collection[int]:
        """Robots known dead."""

    def _roster_wire(self, state: str) -> agreement.WireRoster:
        """The roster this robot announces in a status of ``state``: the agreed set, else its
        proposal while gathering (a life that ends before agreeing must not look committed)."""
        if self.roster is not None:
            return agreement.to_wire(self.roster)
        if state == agreement.GATHERING and self.proposal:
            return agreement.to_wire(self.proposal)
        return ()

    def participants(self) -> list[int]:
        """The agreed participants, in robot-id order (every robot before the agreement)."""
        return sorted(self.roster) if self.roster is not None else list(range(self.config.k))

    @abstractmethod
    async def _wait_news(self, missing: Sequence[int] = ()) -> None:
        """Until something is heard, or one announce period (pulling what may be lost;
        ``missing``: the robots a wait is still for, if it is for some)."""

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
        self.roster = await self._agree(self.start)
        return self.start

    async def _agree(self, start: tuple[int, int]) -> agreement.Roster:
        """The participants every live one of them agreed on (agent.core.roster)."""
        began = self.now()
        outcome: agreement.Outcome = agreement.Waiting(None, (), ())
        try:
            async with asyncio.timeout(self.config.start_timeout):
                while True:
                    boot_over = self.now() - began >= self.config.boot_timeout
                    outcome = agreement.decide(self.robot, start, self.config.k,
                                               self._peer_statuses(), self._dead_robots(),
                                               boot_over)
                    if isinstance(outcome, agreement.StandDown):
                        why = (f"robot {self.robot} stands down: robot {outcome.decided_by} "
                               f"and the others agreed on robots {sorted(outcome.roster)} "
                               "without it")
                        self._say(why)
                        raise StoodDownError(why)
                    if isinstance(outcome, agreement.Agreed):
                        self._agreed(outcome)
                        return outcome.roster
                    if outcome.proposal is not None and outcome.proposal != self.proposal:
                        self.proposal = outcome.proposal
                        self._status("gathering")
                    await self._wait_news()
                    # Deciding costs k^2 (every peer's roster): in a big fleet, where news
                    # comes many times a second, let it pile up between decisions.
                    await asyncio.sleep(DECIDE_SPACING_S * self.config.k)
        except TimeoutError:
            assert isinstance(outcome, agreement.Waiting)
            raise GatherTimeoutError(
                f"{outcome.describe()} within {self.config.start_timeout:g} s "
                f"(mission {self.bus.mission!r}, {self.config.k} robots expected)") from None

    def _agreed(self, outcome: agreement.Agreed) -> None:
        """Announce the agreement (status "agreed", its message naming who is missing)."""
        self.roster = outcome.roster
        dead = sorted(set(outcome.roster) & set(self._dead_robots()))
        notes = []
        if outcome.absent:
            notes.append(f"robots {list(outcome.absent)} never announced a start and take "
                         "no part")
            for robot in outcome.absent:
                self.liveness.declare_absent(robot)
        if dead:
            notes.append(f"robots {dead} died before the mission: the others take over")
        note = "; ".join(notes)
        self._status("agreed", note)
        self._say(f"participants {sorted(outcome.roster)}" + (f"; {note}" if note else ""))

    async def _until(self, missing: Callable[[], list[int]], what: str,
                     check: Callable[[], None] | None = None) -> None:
        """Wait until ``missing()`` is empty (running ``check`` on every news);
        GatherTimeoutError naming the robots still missing."""
        patience = self.config.start_timeout
        try:
            async with asyncio.timeout(patience):
                while waiting_for := missing():
                    if check is not None:
                        check()
                    await self._wait_news(waiting_for)
        except TimeoutError:
            raise GatherTimeoutError(
                f"robots {missing()} did not {what} within {patience:g} s "
                f"(mission {self.bus.mission!r}, {self.config.k} robots expected)") from None
