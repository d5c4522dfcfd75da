"""Body failures ordered at a share of the coverage, armed in simhw ahead of time.

``mstc up --kill-hw ID@progress=P`` used to send simhw its "fail" when the launcher saw the
coverage reach P. A query's round trip under load is tenths of a second, and at time scale 0
a whole mission lasts a second or two: in the chaos campaigns of 2026-12-06 such failures
landed 14.7 points of coverage late in the median (61 at worst, after the mission's end),
where a SIGKILL, which needs no answer, landed 1.0 late. So the launcher now sends each such
order once the mission starts, with the number of covered sub-cells at which coverage
reaches P, and simhw fails the body right after the step that covers the last of them
(``simhw.world.World.arm_failure``). The launcher learns of it from the same cover events,
so it knows the exact coverage it happened at.

Pure bookkeeping; the launcher (deploy/launch.py) does the querying and the printing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from bus.messages import AdminCommand
from deploy.settings import KillOrder


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
