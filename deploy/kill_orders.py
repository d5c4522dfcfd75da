"""The kill orders of one ``mstc up`` mission, carried out (deploy/launch.py calls in):
SIGKILLs and body failures when their moment comes, and body failures ordered at a share of
the coverage armed in simhw ahead of time.

Why armed: ``mstc up --kill-hw ID@progress=P`` used to send simhw its "fail" when the launcher saw the
coverage reach P. A query's round trip under load is tenths of a second, and at time scale 0
a whole mission lasts a second or two: in the chaos campaigns of 2026-12-06 such failures
landed 14.7 points of coverage late in the median (61 at worst, after the mission's end),
where a SIGKILL, which needs no answer, landed 1.0 late. So the launcher now sends each such
order once the mission starts, with the number of covered sub-cells at which coverage
reaches P, and simhw fails the body right after the step that covers the last of them
(``simhw.world.World.arm_failure``). The launcher learns of it from the same cover events,
so it knows the exact coverage it happened at.

``ArmedFailures`` is the pure bookkeeping of the armed orders; ``KillOrders`` does the
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
class ArmedFailure:
    order: KillOrder
    covered: int  # sub-cells covered when simhw fails the body

    def command(self) -> AdminCommand:
        return AdminCommand("fail", self.order.robot, after_covered=self.covered)


def covered_for(percent: float, total: int) -> int:
    """The fewest covered sub-cells of ``total`` at which the coverage is ``percent`` or more
    (rounded to 1e-9 first: 64.4 % of 250 is 161.00000000000003 in floats, and 161 sub-cells
    are 64.4 %)."""
    return min(total, max(0, math.ceil(round(percent * total / 100.0, 9))))


def armable(order: KillOrder) -> bool:
    """Orders simhw can carry out alone: body failures at a coverage."""
    return order.hw and order.percent is not None


class ArmedFailures:
    """The armed orders not yet fired, by robot."""

    def __init__(self) -> None:
        self.armed: dict[int, ArmedFailure] = {}

    def arm(self, order: KillOrder, total: int) -> ArmedFailure:
        assert order.percent is not None, "only coverage orders are armed"
        armed = ArmedFailure(order, covered_for(order.percent, total))
        self.armed[order.robot] = armed
        return armed

    def disarm(self, robot: int) -> None:
        self.armed.pop(robot, None)

    def fired(self, covered: int) -> list[ArmedFailure]:
        """The armed failures that ``covered`` sub-cells set off, removed from the armed."""
        out = [a for a in self.armed.values() if covered >= a.covered]
        for a in out:
            del self.armed[a.order.robot]
        return sorted(out, key=lambda a: (a.covered, a.order.robot))

    @property
    def unfired(self) -> list[KillOrder]:
        return [a.order for a in self.armed.values()]


class KillOrders:
    """One mission's kill orders: due ones carried out, coverage body failures armed.

    ``say`` tells the operator one line (the launcher stamps it with the mission's time).
    """

    def __init__(self, orders: tuple[KillOrder, ...] | list[KillOrder], mission: str,
                 tracker: MissionTracker, supervisor: Supervisor,
                 say: Callable[[str], None]) -> None:
        self.schedule = KillSchedule(orders)
        self.armed = ArmedFailures()
        self.mission = mission
        self.tracker = tracker
        self.supervisor = supervisor
        self.say = say
        self.killed_at: dict[int, float] = {}  # robots failed by us, until a peer notices

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
        """Send simhw the coverage body failures (when the mission starts)."""
        for order in self.schedule.take(armable):
            armed = self.armed.arm(order, self.tracker.total)
            replies = await bus.query(keys.hw_admin(self.mission), armed.command(),
                                      AdminReply, timeout=2.0)
            if not replies or not replies[0].msg.ok:
                why = replies[0].msg.message if replies else "no answer from simhw"
                self.say(f"cannot arm {order.describe()} in simhw ({why}); it is sent when "
                         f"due instead")
                self.armed.disarm(order.robot)
                self.schedule.pending.append(order)
                continue
            self.tracker.failing[order.robot] = BODY_FAILED
        self.fire_armed()

    def fire_armed(self) -> None:
        """Tell the armed failures the coverage heard so far has set off."""
        t = self.tracker
        for armed in self.armed.fired(t.covered):
            self.killed_at[armed.order.robot] = time.monotonic()
            t.lose(armed.order.robot, BODY_FAILED)
            # the coverage simhw failed it at: exactly its order's, not when we heard
            self.say(f"{armed.order.describe()}: done "
                     f"(coverage {100.0 * armed.covered / t.total:.1f} %)")

    async def _fail_body(self, bus: Bus, robot: int) -> None:
        replies = await bus.query(keys.hw_admin(self.mission), AdminCommand("fail", robot),
                                  AdminReply, timeout=2.0)
        if not replies or not replies[0].msg.ok:
            why = replies[0].msg.message if replies else "no answer from simhw"
            self.say(f"cannot fail robot {robot}'s body: {why}")
            return
        self.tracker.lose(robot, BODY_FAILED)
