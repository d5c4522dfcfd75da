"""Drives one robot's OfflineRobot state machine with the body and the bus.

The machine (planner.offline) decides; this module only carries its decisions out: a MoveTo
becomes turns and a forward step of the body, then a Progress message; a takeover decision
becomes RobotEvents; WaitFor waits for news (a death, coverage) and meanwhile pulls the
others' re-learnable state, so coverage missed during a router outage is learned again.
"""

from __future__ import annotations

import time
from collections.abc import Awaitable, Callable

from agent.offline.hardware import Hardware
from agent.offline.peers import PeerTable
from bus import keys
from bus.bridge import Bus
from bus.messages import EventKind, Progress, RobotEvent
from planner.offline.machine import Finished, MoveTo, OfflineRobot, WaitFor


class OfflineRunner:
    """Walk the plan, take over dead robots' sections, stop when all is covered."""

    def __init__(self, bus: Bus, hardware: Hardware, peers: PeerTable, machine: OfflineRobot,
                 incarnation: int, *, refresh: Callable[[], Awaitable[None]],
                 refresh_period: float) -> None:
        self.bus = bus
        self.hardware = hardware
        self.peers = peers
        self.machine = machine
        self.robot = machine.robot
        self.incarnation = incarnation
        self.moves = 0
        self.took_over: list[int] = []
        self.phase = "covering"
        self._refresh = refresh
        self._refresh_period = refresh_period
        self._targets: dict[int, int] = {}  # cycle index -> dead robot whose takeover ends there
        self._section_announced = False
        self._refreshed = -float("inf")

    def event(self, kind: EventKind, subject: int | None = None, detail: str = "") -> None:
        self.bus.publish(keys.events(self.bus.mission, self.robot),
                         RobotEvent(self.robot, self.incarnation, kind, subject, detail))

    async def run(self) -> None:
        self.event("started", detail=f"{self.machine.own_steps_left} moves planned")
        while True:
            if self.machine.about_to_take_over:
                # The decision is only as good as what we know of the dead robot's coverage:
                # merge what the others know first (our own copy may lag or have gaps).
                self._refreshed = time.monotonic()
                await self._refresh()
            action = self.machine.next_action()
            self._announce_decisions()
            self._announce_section()
            if isinstance(action, Finished):
                self.phase = "done"
                return
            if isinstance(action, WaitFor):
                self.phase = f"watching {action.watching}"
                if time.monotonic() - self._refreshed >= self._refresh_period:
                    self._refreshed = time.monotonic()
                    await self._refresh()
                await self.peers.wait_news(self._refresh_period)
                continue
            self.phase = "covering" if not self.machine.section_done else "taking over"
            await self._move(action)

    async def _move(self, action: MoveTo) -> None:
        await self.hardware.step_to(action.sub)
        index = self.machine.on_moved()
        self.moves += 1
        self.bus.publish(keys.progress(self.bus.mission, self.robot),
                         Progress(self.robot, self.incarnation, self.moves, action.sub,
                                  self.hardware.state.sim_time))
        dead = self._targets.pop(index, None)
        if dead is not None:
            self.event("takeover_finished", dead, f"reached cycle index {index}")

    def _announce_decisions(self) -> None:
        for decision in self.machine.pop_decisions():
            self.took_over.append(decision.dead)
            if decision.target is None:
                self.event("takeover_started", decision.dead, "nothing left to cover")
                self.event("takeover_finished", decision.dead, "nothing left to cover")
            else:
                self._targets[decision.target] = decision.dead
                self.event("takeover_started", decision.dead,
                           f"walking to cycle index {decision.target}")

    def _announce_section(self) -> None:
        if self.machine.section_done and not self._section_announced:
            self._section_announced = True
            self.event("section_complete", detail=f"{self.moves} moves")
