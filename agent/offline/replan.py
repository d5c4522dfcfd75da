"""The fleet's side of re-balancing after a death (``--recovery rebalance``): the reports
every survivor re-plans from.

When a robot learns of a death, it stops after its current move and announces a
ReplanReport: the robots it knows dead (the re-plan's *epoch*), where it stands, the route it
still has and what it knows covered. Once it holds, for its epoch, the report of every robot
not known dead, it re-plans with planner.offline.rebalance from those reports alone — never
from its own later knowledge — so every survivor computes the same re-plan, and the digest
of the reports it used says so in its "replanned" event. A death heard meanwhile starts a new
epoch (the newly dead robot's report, if any, no longer counts); a report of an older epoch is
kept until its sender catches up.
"""

from __future__ import annotations

import hashlib
from collections.abc import Collection
from dataclasses import dataclass

import numpy as np

from bus import keys
from bus.drops import DropCounter
from bus.messages import ReplanReport, unpack_covered
from planner.offline.rebalance import Replan, Survivor, plan_order, rebalance
from planner.types import BoolArray, Cycle, IntArray, Plan


class ReplanBoard:
    """The latest ReplanReport of each robot flying ``plan``. Only the
    plan's robots (the agreed participants) take part in a re-plan: a robot that never
    announced its start has no section, and its death changes nothing."""

    def __init__(self, plan: Plan, drops: DropCounter) -> None:
        self.cycle = plan.cycle
        self.members = tuple(sorted(rp.robot for rp in plan.robots))
        self.drops = drops
        self.rank = plan_order(plan)
        self.reports: dict[int, ReplanReport] = {}

    def on_report(self, key: str, msg: ReplanReport) -> bool:
        """Keep ``msg`` if it makes sense; True when it is news."""
        n = self.cycle.n
        parsed = keys.parse(key)
        problem = ""
        if msg.robot not in self.members or (parsed is not None and parsed.robot != msg.robot):
            problem = f"replan report of robot {msg.robot} (no member of the plan) on {key}"
        elif not all(0 <= i < n for i in (msg.position, *msg.route)):
            problem = f"replan report of robot {msg.robot} names places off the {n}-cycle"
        else:
            try:
                unpack_covered(msg.covered, n)
            except ValueError as error:
                problem = f"replan report of robot {msg.robot}: {error}"
        if problem:
            self.drops.count("replan", "invalid", problem)
            return False
        known = self.reports.get(msg.robot)
        if known is not None and (msg.incarnation, len(msg.dead)) < (known.incarnation,
                                                                     len(known.dead)):
            return False  # an older life's, or an older epoch's re-announcement
        self.reports[msg.robot] = msg
        return known != msg

    def epoch(self, dead: Collection[int]) -> tuple[int, ...]:
        """The re-plan epoch of the robots known dead: the plan's robots among them."""
        return tuple(r for r in self.members if r in dead)

    def missing(self, dead: tuple[int, ...]) -> list[int]:
        """Members not in ``dead`` whose report for epoch ``dead`` is not here yet."""
        return [r for r in self.members if r not in dead
                and (r not in self.reports or self.reports[r].dead != dead)]

    def positions(self, dead: tuple[int, ...]) -> dict[int, int]:
        """Where each robot of epoch ``dead`` reported to stand."""
        return {r: report.position for r, report in self.reports.items()
                if r not in dead and report.dead == dead}

    def inputs(self, dead: tuple[int, ...]) -> ReplanInputs:
        """What the re-plan of epoch ``dead`` (every report present) is made from: a copy,
        so that it can be computed off the event loop while reports keep arriving."""
        used = [self.reports[r] for r in self.members if r not in dead]
        covered = np.zeros(self.cycle.n, dtype=bool)
        digest = hashlib.sha256(f"mstc-replan/1 dead={dead}\n".encode())
        for report in used:
            covered |= unpack_covered(report.covered, self.cycle.n)
            digest.update(f"{report.robot} at {report.position} route {report.route}\n"
                          .encode())
        digest.update(np.packbits(covered).tobytes())
        survivors = tuple(Survivor(r.robot, r.position, r.route) for r in used)
        return ReplanInputs(self.cycle, covered, survivors, self.rank, digest.hexdigest())


@dataclass(frozen=True)
class ReplanInputs:
    """One epoch's re-plan inputs and the digest of the reports they came from."""

    cycle: Cycle
    covered: BoolArray
    survivors: tuple[Survivor, ...]
    rank: IntArray
    digest: str

    def solve(self) -> Replan:
        """The re-plan (pure; a second or more of CPU in a large fleet)."""
        return rebalance(self.cycle, self.covered, self.survivors, self.rank)
