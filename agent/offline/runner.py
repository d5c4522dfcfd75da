"""Drives one robot's plan-walking state machine (the registry's for its algorithm) with the
body and the bus.

The machine (planner.offline) decides; this module only carries its decisions out: a MoveTo
becomes turns and a forward step of the body, then a Progress message; a takeover decision
becomes RobotEvents; WaitFor waits for news (a death, coverage) and meanwhile pulls the
others' re-learnable state, so coverage missed during a router outage is learned again.

With ``--recovery rebalance`` every step also goes through planner.offline.traffic (the
lockstep's deconfliction, fed with agent.offline.bodies' knowledge of the other bodies): a
MoveTo may wait for a body in the way or step aside first, a robot with nothing to walk
steps aside for one whose next sub-cell it stands on, and a bump makes it decide again.
"""

from __future__ import annotations

import asyncio
import logging
import time
from collections.abc import Awaitable, Callable, Sequence
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Protocol

import numpy as np

from agent.core.errors import HardwareError
from agent.offline.apart import apart_from
from agent.offline.bodies import Bodies
from agent.offline.hardware import Hardware
from agent.offline.peers import PeerTable
from agent.offline.replan import (
    ReplanBoard,
    ReplanInputs,
    Routes,
    routes_apart,
    share_wait,
)
from bus import keys
from bus.bridge import Bus
from bus.messages import (
    EventKind,
    Progress,
    ReplanReport,
    ReplanShare,
    RobotEvent,
    pack_covered,
    pack_routes,
)
from planner.offline.machine import Finished, MoveTo, PlanRobot, WaitFor
from planner.offline.traffic import Go, Hold, Traffic

# How long bumps into the same sub-cell, one after the other, may go on before the body
# counts as failed (a body simhw holds that nobody knows of: a robot outside the plan).
BUMP_PATIENCE_S = 30.0
BUMP_RETRY_S = 0.05
# A robot with a route to walk that has not moved for this long says why in its log (and
# again each time as long): what stops it and where it believes the others are, the
# evidence a stalled fleet leaves.
STILL_WARN_S = 5.0

_log = logging.getLogger("mstc.agent")


class CrowdPulls(Protocol):
    """How a robot of a crowded fleet pulls what it may have lost: never every robot's state
    at once (agent.offline.driver.OfflineAgent)."""

    async def in_turn(self) -> None:
        """Some robots' state, the next ones in turn (a watcher's backstop)."""

    async def each(self, robots: Sequence[int]) -> None:
        """The state of each of ``robots`` (the survivors whose report is missing)."""


class OfflineRunner:
    """Walk the plan, take over dead robots' sections, stop when all is covered."""

    def __init__(self, bus: Bus, hardware: Hardware, peers: PeerTable, machine: PlanRobot,
                 incarnation: int, *, refresh: Callable[[], Awaitable[None]],
                 refresh_period: float, pull: Callable[[int], Awaitable[None]] | None = None,
                 crowd: CrowdPulls | None = None,
                 board: ReplanBoard | None = None,
                 announce: Callable[[str, Any], None] | None = None,
                 quiet: Callable[[str], None] | None = None,
                 bodies: Bodies | None = None) -> None:
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
        self._pull = pull
        self._crowd = crowd
        self._refresh_period = refresh_period
        self._targets: dict[int, int] = {}  # cycle index -> dead robot whose takeover ends there
        self._section_announced = False
        self._refreshed = -float("inf")
        # --recovery rebalance: the reports to re-plan from, how to announce ours, and the
        # dead robots of the last re-plan (its epoch)
        self.board = board
        self._announce = announce
        self._quiet = quiet
        self._epoch: tuple[int, ...] = ()
        # --recovery rebalance: the other bodies as known, and this body's deconfliction
        self.bodies = bodies
        self.lane = None if bodies is None else Traffic(self.robot, machine.cycle,
                                                        machine.position)
        self._bumping: tuple[int, float] | None = None  # (place, since) of repeated bumps
        self._still_since = time.monotonic()  # the body's last move (or a re-plan)
        self._still_said = -float("inf")

    def event(self, kind: EventKind, subject: int | None = None, detail: str = "") -> None:
        self.bus.publish(keys.events(self.bus.mission, self.robot),
                         RobotEvent(self.robot, self.incarnation, kind, subject, detail))

    async def run(self) -> None:
        self.event("started", detail=f"{self.machine.own_steps_left} moves planned")
        while True:
            if self.board is not None and self._dead() != self._epoch \
                    and not self.machine.all_covered:
                await self._replan()
                continue
            if self.machine.about_to_take_over:
                # The decision is only as good as what we know of the dead robot's coverage:
                # merge what the others know first (our own copy may lag or have gaps).
                self._refreshed = time.monotonic()
                await self._refresh()
            action = self.machine.next_action()
            self._announce_decisions()
            self._announce_section()
            if isinstance(action, Finished) or (self.lane is not None
                                                and self.machine.all_covered):
                self.phase = "done"
                return
            if isinstance(action, WaitFor):
                self.phase = f"watching {action.watching}"
                if self.lane is not None and await self._drive(None):
                    continue
                if time.monotonic() - self._refreshed >= self._refresh_period:
                    self._refreshed = time.monotonic()
                    await (self._refresh() if self._crowd is None else self._crowd.in_turn())
                await self.peers.wait_news(self._refresh_period)
                continue
            self.phase = "covering" if not self.machine.section_done else "taking over"
            if self.lane is None:
                await self._move(action)
            elif not await self._drive(action):
                await self.peers.wait_news(self._refresh_period)

    def traffic_detail(self) -> str:
        """The deconfliction's counts, for the "completed" event (empty without it)."""
        if self.lane is None:
            return ""
        return self.lane.counts.describe()

    async def _drive(self, action: MoveTo | None) -> bool:
        """One deconflicted step towards ``action`` (None: only make way); True if the body
        moved (or walked a plan step in place)."""
        assert self.lane is not None and self.bodies is not None
        plan_next = None if action is None else action.index
        step = self.lane.decide(plan_next, self.bodies.peers(self.machine.dead))
        if not isinstance(step, Go):
            if action is not None:
                self._say_still(step)
            return False
        if step.target == self.lane.at:
            self.machine.on_moved()
            self._still_since = time.monotonic()
            return True
        if not await self.hardware.try_step_to(self.machine.cycle.at(step.target)):
            self.lane.bumped()
            # a body holds the target: if none was known there, the one that walked there
            # unheard of is placed there (its Progress lost), and the rule decides from that
            self.bodies.on_bump(step.target, self.machine.dead)
            now = time.monotonic()
            if self._bumping is None or self._bumping[0] != step.target:
                self._bumping = (step.target, now)
            elif now - self._bumping[1] > BUMP_PATIENCE_S:
                raise HardwareError(f"robot {self.robot}: bumped into "
                                    f"{self.machine.cycle.at(step.target)} for "
                                    f"{now - self._bumping[1]:.0f} s")
            self._say_still(step)
            await self.peers.wait_news(BUMP_RETRY_S)
            return False
        self._bumping = None
        self._still_since = time.monotonic()
        if step.on_plan:
            self.machine.on_moved()
        else:
            self.machine.on_covered(step.target)
        self.lane.moved(step)
        self._moved(self.machine.cycle.at(step.target))
        return True

    def _say_still(self, step: Go | Hold) -> None:
        """Log why the body has not moved for STILL_WARN_S (at most once per that time)."""
        assert self.lane is not None and self.bodies is not None
        now = time.monotonic()
        if now - max(self._still_since, self._still_said) < STILL_WARN_S:
            return
        self._still_said = now
        at = self.machine.cycle.at
        why = (f"bumping into {at(step.target)}" if isinstance(step, Go)
               else f"waiting for robot {step.blocker}" if step.blocker is not None
               else "giving way")
        known = "; ".join(
            f"{p.robot} at {at(p.position)}"
            + (f" next {at(p.ahead[0])}" if p.ahead else " next unknown" if p.lost else "")
            + (" (on its way back)" if p.returning else "")
            for p in self.bodies.peers(self.machine.dead))
        route = self.machine.pending_route
        _log.warning("robot %d has not moved for %.0f s (%s): at %s, %s, plan's next %s; "
                     "the others as known: %s", self.robot, now - self._still_since,
                     self.phase, at(self.lane.at), why, at(route[0]) if route else "-",
                     known or "none")

    def _dead(self) -> tuple[int, ...]:
        """The re-plan epoch: the plan's robots known dead (a robot that never took part
        and is declared dead later causes no re-plan)."""
        assert self.board is not None
        return self.board.epoch(self.machine.dead)

    async def _replan(self) -> None:
        """Stop, announce where we are, wait for every survivor's report of this epoch and
        walk the re-plan (agent.offline.replan); a new death restarts with a new epoch."""
        assert self.board is not None and self._announce is not None
        dead = self._dead()
        self.phase = "re-planning"
        m = self.machine
        at, route = m.position, m.pending_route
        if self.lane is not None:
            at, route = self.lane.at, self.lane.walk(route)
        mine = ReplanReport(self.robot, self.incarnation, dead, at, route,
                            pack_covered(m.covered), self.hardware.state.sim_time)
        self.board.on_report(keys.replan(self.bus.mission, self.robot), mine)
        self._announce(keys.replan(self.bus.mission, self.robot), mine)
        stopped = time.monotonic()
        if self._crowd is not None:
            # every survivor publishes its report at this moment, and re-announces it: in a
            # crowd a pull now (each survivor asking the others for all they hold) only
            # competes with them; the first pull for missing reports waits a period
            self._refreshed = stopped
        while self._dead() == dead and not m.all_covered:
            if not self.board.missing(dead):
                inputs = self.board.inputs(dead)
                reported = time.monotonic()
                made = await self._replan_of(inputs)
                if made is None:
                    continue  # a new death, or all covered, while waiting for the share
                routes, how = made
                for index in np.flatnonzero(inputs.covered):
                    m.on_covered(int(index))
                route = routes[self.robot]
                m.on_replan(route)
                if self.lane is not None and self.bodies is not None:
                    self.lane.rejoin()
                    self.bodies.on_replan(routes, self.board.stops(dead))
                self._epoch = dead
                self._still_since = time.monotonic()
                if self._quiet is not None:
                    # re-planned: a survivor still missing our report pulls it (every
                    # survivor re-publishing its report each period for the rest of the
                    # mission flooded a slow link between hosts: docs/operations.md)
                    self._quiet(keys.replan(self.bus.mission, self.robot))
                # how long the reports and the re-plan took: a crowded fleet's stall
                done = time.monotonic()
                self.event("replanned", None, f"dead {list(dead)}, digest {inputs.digest[:16]}, "
                                              f"{len(route)} moves to walk{how} (reports "
                                              f"{reported - stopped:.1f} s, re-plan "
                                              f"{done - reported:.1f} s)")
                return
            await self._wait_reports(dead)

    async def _wait_reports(self, dead: tuple[int, ...]) -> None:
        if time.monotonic() - self._refreshed >= self._refresh_period:
            self._refreshed = time.monotonic()
            if self._crowd is None:
                await self._refresh()
            else:
                assert self.board is not None
                await self._crowd.each(self.board.missing(dead))
        await self.peers.wait_news(self._refresh_period)

    async def _replan_of(self, inputs: ReplanInputs) -> tuple[Routes, str] | None:
        """The re-plan of ``inputs`` and how it was had (for the event): computed here, or
        in a crowded fleet shared by the epoch's sharer (agent.offline.replan); None if the
        epoch ended while waiting for the share."""
        assert self.board is not None and self._announce is not None
        sharer = self.board.sharer(inputs.dead)
        if sharer is None:
            return await self._solve(inputs)
        if sharer == self.robot:
            routes, where = await self._solve(inputs, apart=True)
            share = ReplanShare(self.robot, self.incarnation, inputs.dead, inputs.digest,
                                tuple(routes), tuple(len(r) for r in routes.values()),
                                pack_routes(list(routes.values())))
            self._announce(keys.replan_share(self.bus.mission, self.robot), share)
            return routes, f", shared with the fleet{where}"
        wait = share_wait(len(inputs.survivors), inputs.cycle.n)
        deadline = time.monotonic() + wait
        self.phase = f"waiting for robot {sharer}'s re-plan"
        while self._dead() == inputs.dead and not self.machine.all_covered:
            shared = self.board.shared(inputs)
            if shared is not None and not shared.problem:
                return shared.routes, f", shared by robot {shared.sender}"
            if shared is not None:
                routes, where = await self._solve(inputs)
                return routes, f", computed here: robot {sharer}'s {shared.problem}{where}"
            if time.monotonic() >= deadline:
                routes, where = await self._solve(inputs)
                return routes, f", computed here: robot {sharer}'s not heard in {wait:.0f} s{where}"
            # The sharer re-announces its share every period; the backstop for a lost one
            # asks the sharer alone: 59 survivors pulling every robot's state while they
            # waited kept the sharer answering their queries instead of computing.
            if self._pull is not None \
                    and time.monotonic() - self._refreshed >= self._refresh_period:
                self._refreshed = time.monotonic()
                await self._pull(sharer)
            await self.peers.wait_news(self._refresh_period)
        return None

    async def _solve(self, inputs: ReplanInputs, *, apart: bool | None = None
                     ) -> tuple[Routes, str]:
        """The re-plan's routes, computed here off the loop, and a note for the event when
        it was not where it should have been. In a process of its own when ``apart`` (by
        default for a large map, agent.offline.apart.apart_from), else in a
        thread: at 100 robots a re-plan is a second or more of CPU, and a blocked loop sends
        no heartbeats (under load, peers declared robots that were re-planning dead: chaos
        campaign of 2026-12-02, trial 41)."""
        if apart is None:
            apart = apart_from(inputs.cycle.n)
        where = ""
        if apart:
            try:
                return await routes_apart(inputs)  # and why not in a session of its own
            except (OSError, BrokenProcessPool) as error:
                # no process to be had (no /dev/shm for its locks, a worker killed): the
                # same re-plan in a thread, later in a crowd, and the event says so
                where = f" (computed in a thread: no process for it: {error})"
        return await asyncio.to_thread(inputs.routes), where

    async def _move(self, action: MoveTo) -> None:
        await self.hardware.step_to(action.sub)
        index = self.machine.on_moved()
        self._moved(action.sub)
        dead = self._targets.pop(index, None)
        if dead is not None:
            self.event("takeover_finished", dead, f"reached cycle index {index}")

    def _moved(self, sub: tuple[int, int]) -> None:
        self.moves += 1
        self.bus.publish(keys.progress(self.bus.mission, self.robot),
                         Progress(self.robot, self.incarnation, self.moves, sub,
                                  self.hardware.state.sim_time))

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
