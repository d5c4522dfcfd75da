"""The kill orders of one ``mstc up`` mission, carried out (deploy/launch.py calls in):
those at a time when it comes, those at a share of the coverage armed in simhw ahead of time.

Why armed. The launcher hears coverage from simhw's cover events, and at time scale 0 it
falls behind: a whole mission lasts a second or two, and it handles every message of every
robot. Orders sent when the launcher saw their coverage landed late. In the chaos campaigns'
records on this machine (2026-12-06), body failures landed 14.7 points of coverage late in
the median (61 at worst, after the mission's end: they also wait for simhw's answer), and a
SIGKILL ordered at 38.1 % found its robot still covering at 68.7 % (the launcher had
heard 46.2 %). So when the mission starts the launcher sends simhw the number of covered
sub-cells each order stands for, and simhw acts right after the step that covers the last
of them: it fails the body itself ("fail", ``simhw.world.World.arm_failure``), or, for a
SIGKILL, which only the launcher can send, holds every body ("pause",
``World.pause_at``) until the launcher, once it has heard that coverage, has killed the
agent and says "resume". Either way the death lands at the ordered coverage, and the
launcher knows the exact figure.

``ArmedOrders`` is the pure bookkeeping of the armed orders; ``KillOrders`` does the
querying, the signalling and the telling.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

from bus import keys
from bus.bridge import Bus
from bus.messages import AdminCommand, AdminReply
from deploy.settings import KillOrder
from deploy.summary import MissionTracker
from deploy.supervisor import KillSchedule, Supervisor

BODY_FAILED = "body failed by mstc up"
KILLED = "killed by mstc up (SIGKILL)"


@dataclass(frozen=True)
class ArmedOrder:
    order: KillOrder
    covered: int  # sub-cells covered when simhw fails the body or holds the world

    def command(self) -> AdminCommand:
        if self.order.hw:
            return AdminCommand("fail", self.order.robot, after_covered=self.covered)
        # a process simhw cannot kill: it holds the world there until we have
        return AdminCommand("pause", None, after_covered=self.covered)


def covered_for(percent: float, total: int) -> int:
    """The fewest covered sub-cells of ``total`` at which the coverage is ``percent`` or more
    (rounded to 1e-9 first: 64.4 % of 250 is 161.00000000000003 in floats, and 161 sub-cells
    are 64.4 %)."""
    return min(total, max(0, math.ceil(round(percent * total / 100.0, 9))))


def armable(order: KillOrder, total: int) -> bool:
    """Orders at a coverage short of all ``total`` sub-cells: simhw fails the body itself, or
    holds the world for a SIGKILL. One due only with every sub-cell covered is not armed: a
    death then tests nothing, and the launcher lists it as not carried out."""
    return order.percent is not None and covered_for(order.percent, total) < total


class ArmedOrders:
    """The armed orders not yet fired, by robot."""

    def __init__(self) -> None:
        self.armed: dict[int, ArmedOrder] = {}

    def arm(self, order: KillOrder, total: int) -> ArmedOrder:
        assert order.percent is not None, "only coverage orders are armed"
        armed = ArmedOrder(order, covered_for(order.percent, total))
        self.armed[order.robot] = armed
        return armed

    def disarm(self, robot: int) -> None:
        self.armed.pop(robot, None)

    def fired(self, covered: int) -> list[ArmedOrder]:
        """The armed orders that ``covered`` sub-cells set off, removed from the armed."""
        out = [a for a in self.armed.values() if covered >= a.covered]
        for a in out:
            del self.armed[a.order.robot]
        return sorted(out, key=lambda a: (a.covered, a.order.robot))

    @property
    def unfired(self) -> list[KillOrder]:
        return [a.order for a in self.armed.values()]


class KillOrders:
    """One mission's kill orders: those at a time carried out when due, those at a coverage
    armed in simhw and carried out (SIGKILL) or told (body failure) when heard.

    ``say`` tells the operator one line (the launcher stamps it with the mission's time).
    """

    def __init__(self, orders: tuple[KillOrder, ...] | list[KillOrder], mission: str,
                 tracker: MissionTracker, supervisor: Supervisor,
                 say: Callable[[str], None]) -> None:
        self.schedule = KillSchedule(orders)
        self.armed = ArmedOrders()
        self.mission = mission
        self.tracker = tracker
        self.supervisor = supervisor
        self.say = say
        self.killed_at: dict[int, float] = {}  # robots failed by us, until a peer notices
        self.resume_due = False  # simhw holds the world for a SIGKILL we have now sent

    def waits_on_coverage(self) -> bool:
        return self.schedule.waits_on_coverage(self.tracker.coverage)

    @property
    def unfired(self) -> list[KillOrder]:
        """Kill orders the mission ended before."""
        return [*self.schedule.pending, *self.armed.unfired]

    def noticed(self, robot: int) -> str:
        """How long ago we failed ``robot`` (" 0.13 s after it was failed"), or ""."""
        killed_at = self.killed_at.get(robot)
        return "" if killed_at is None else \
            f" {time.monotonic() - killed_at:.2f} s after it was failed"

    def forget(self, robot: int) -> None:
        self.killed_at.pop(robot, None)

    async def run_due(self, bus: Bus, elapsed: float) -> None:
        t = self.tracker
        for order in self.schedule.due(elapsed=elapsed, coverage=t.coverage):
            self.killed_at[order.robot] = time.monotonic()
            if order.hw:
                await self._fail_body(bus, order.robot)
            else:
                self.supervisor.kill_agent(order.robot)
                t.lose(order.robot, KILLED)
            self.say(f"{order.describe()}: done (coverage {t.coverage:.1f} %)")

    async def arm(self, bus: Bus) -> None:
        """Send simhw the orders at a coverage (when the mission starts)."""
        total = self.tracker.total
        for order in self.schedule.take(lambda o: armable(o, total)):
            armed = self.armed.arm(order, total)
            replies = await bus.query(keys.hw_admin(self.mission), armed.command(),
                                      AdminReply, timeout=2.0)
            if not replies or not replies[0].msg.ok:
                why = replies[0].msg.message if replies else "no answer from simhw"
                self.say(f"cannot arm {order.describe()} in simhw ({why}); it is sent when "
                         f"due instead")
                self.armed.disarm(order.robot)
                self.schedule.pending.append(order)
                continue
            if order.hw:
                self.tracker.failing[order.robot] = BODY_FAILED
        self.fire_armed()

    def fire_armed(self) -> bool:
        """Carry out (SIGKILL) or tell (body failures) the armed orders the coverage heard so
        far has set off; True if simhw now waits for a "resume"."""
        t = self.tracker
        for armed in self.armed.fired(t.covered):
            order = armed.order
            self.killed_at[order.robot] = time.monotonic()
            if order.hw:
                t.lose(order.robot, BODY_FAILED)
            else:
                self.supervisor.kill_agent(order.robot)
                t.lose(order.robot, KILLED)
                self.resume_due = True
            # the coverage it happened at in simhw: exactly its order's, not when we heard
            self.say(f"{order.describe()}: done "
                     f"(coverage {100.0 * armed.covered / t.total:.1f} %)")
        return self.resume_due

    async def resume_if_due(self, bus: Bus) -> None:
        """Let simhw's world go on after the SIGKILLs it was held for (retried per tick)."""
        if not self.resume_due:
            return
        # Cleared before asking: once simhw resumes, the world may reach the next pause and
        # its kill set the flag again before this answer is back.
        self.resume_due = False
        replies = await bus.query(keys.hw_admin(self.mission), AdminCommand("resume"),
                                  AdminReply, timeout=2.0)
        if not replies or not replies[0].msg.ok:
            why = replies[0].msg.message if replies else "no answer from simhw"
            self.say(f"cannot resume simhw's world after a kill: {why}; trying again")
            self.resume_due = True

    async def _fail_body(self, bus: Bus, robot: int) -> None:
        replies = await bus.query(keys.hw_admin(self.mission), AdminCommand("fail", robot),
                                  AdminReply, timeout=2.0)
        if not replies or not replies[0].msg.ok:
            why = replies[0].msg.message if replies else "no answer from simhw"
            self.say(f"cannot fail robot {robot}'s body: {why}")
            return
        self.tracker.lose(robot, BODY_FAILED)
