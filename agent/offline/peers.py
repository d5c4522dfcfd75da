"""What one robot knows about the others: starts, plan digests, coverage, deaths, the mission.

Handlers run on the event loop (the bus bridge calls them) and only update this table and
wake the waiters; messages that decode but make no sense (a robot id outside the fleet, a
key naming another robot than the message, a sub-cell off the cycle) are counted as drops
with reason "invalid" and otherwise ignored. Coverage and deaths heard before the plan
exists are kept and replayed into the robot's state machine once it does.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass, field

from bus import keys
from bus.drops import DropCounter
from bus.messages import (
    AgentState,
    DeathNotice,
    MissionStatus,
    Progress,
    RobotStatus,
    unpack_covered,
)
from planner.offline.machine import PlanRobot
from planner.types import SubCell


@dataclass
class PeerTable:
    """Knowledge of robot ``robot`` about a fleet of ``k``; ``changed`` is set on news."""

    robot: int
    k: int
    drops: DropCounter
    statuses: dict[int, RobotStatus] = field(default_factory=dict)
    dead: dict[int, DeathNotice] = field(default_factory=dict)
    early_cells: dict[SubCell, str] = field(default_factory=dict)  # cell -> key heard on
    mission: MissionStatus | None = None
    machine: PlanRobot | None = None
    changed: asyncio.Event = field(default_factory=asyncio.Event)
    verdict: asyncio.Event = field(default_factory=asyncio.Event)  # mission no longer running

    # --- validation -----------------------------------------------------------------------

    def _valid(self, key: str, robot: int, what: str) -> bool:
        parsed = keys.parse(key)
        kind = keys.kind_of(key)
        if not 0 <= robot < self.k:
            self.drops.count(kind, "invalid",
                             f"{what} about robot {robot}; the fleet is 0..{self.k - 1}")
            return False
        if parsed is not None and parsed.robot is not None and parsed.robot != robot \
                and parsed.kind != "state":
            self.drops.count(kind, "invalid", f"{what} of robot {robot} on {key}")
            return False
        return True

    def _invalid(self, key: str, detail: str) -> None:
        self.drops.count(keys.kind_of(key), "invalid", detail)

    def _news(self) -> None:
        self.changed.set()

    # --- handlers -------------------------------------------------------------------------

    def on_status(self, key: str, msg: RobotStatus) -> None:
        if not self._valid(key, msg.robot, "status"):
            return
        known = self.statuses.get(msg.robot)
        if known is not None and msg.incarnation < known.incarnation:
            return  # an older life's re-announcement
        if known is not None and msg.incarnation == known.incarnation \
                and tuple(msg.start) != tuple(known.start):
            self._invalid(key, f"robot {msg.robot} changed its start {known.start} -> "
                               f"{msg.start} within one life")
            return
        self.statuses[msg.robot] = msg
        self._news()

    def on_progress(self, key: str, msg: Progress) -> None:
        if not self._valid(key, msg.robot, "progress"):
            return
        self.covered_cell(key, (msg.cell[0], msg.cell[1]))

    def covered_cell(self, key: str, cell: SubCell) -> None:
        if self.machine is None:
            self.early_cells.setdefault(cell, key)
            return
        index = self.machine.cycle.position(cell)
        if index < 0:
            self._invalid(key, f"covered sub-cell {cell} is not on the cycle")
            return
        if not self.machine.covered[index]:
            self.machine.on_covered(index)
            self._news()

    def on_death(self, notice: DeathNotice) -> None:
        if not 0 <= notice.robot < self.k:
            self.drops.count("death", "invalid", f"death of robot {notice.robot}")
            return
        known = self.dead.get(notice.robot)
        if known is not None and known.incarnation >= notice.incarnation:
            return
        self.dead[notice.robot] = notice
        if self.machine is not None and self._life_is_planned(notice):
            self.machine.on_dead(notice.robot)
        self._news()

    def _life_is_planned(self, notice: DeathNotice) -> bool:
        """A death counts for the plan only if it is the planned life (or a later one)."""
        status = self.statuses.get(notice.robot)
        return status is None or notice.incarnation >= status.incarnation

    def on_mission(self, key: str, msg: MissionStatus) -> None:
        if self.mission is not None and self.mission.state != "running" \
                and msg.state == "running":
            return  # a final verdict is not undone by a stale "running"
        self.mission = msg
        if msg.state != "running":
            self.verdict.set()
        if msg.state == "complete" and self.machine is not None:
            for index in range(self.machine.cycle.n):
                self.machine.on_covered(index)
        self._news()

    def on_state(self, key: str, msg: AgentState) -> None:
        """Another robot's knowledge (a state query reply): merge its coverage and deaths."""
        if not self._valid(key, msg.robot, "agent state") or self.machine is None:
            return
        if msg.n != self.machine.cycle.n:
            self._invalid(key, f"agent state for a {msg.n}-cycle; ours has "
                               f"{self.machine.cycle.n}")
            return
        try:
            covered = unpack_covered(msg.covered, msg.n)
        except ValueError as error:
            self._invalid(key, f"agent state coverage: {error}")
            return
        fresh = covered & ~self.machine.covered
        for index in fresh.nonzero()[0]:
            self.machine.on_covered(int(index))
        if fresh.any():
            self._news()

    # --- use ------------------------------------------------------------------------------

    def attach(self, machine: PlanRobot) -> None:
        """Hand over to the robot's state machine what was heard before it existed."""
        self.machine = machine
        for cell, key in sorted(self.early_cells.items()):
            self.covered_cell(key, cell)
        self.early_cells.clear()
        for notice in self.dead.values():
            if self._life_is_planned(notice):
                machine.on_dead(notice.robot)

    def missing_digests(self, participants: list[int]) -> list[int]:
        """Participants whose plan digest is still unknown (robots known dead need none)."""
        return [r for r in participants
                if r not in self.dead
                and not (r in self.statuses and self.statuses[r].plan_digest)]

    async def wait_news(self, timeout: float) -> None:
        """Wait until something changes or ``timeout`` seconds pass."""
        try:
            async with asyncio.timeout(timeout):
                await self.changed.wait()
        except TimeoutError:
            pass
        self.changed.clear()
