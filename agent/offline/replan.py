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

In a crowded fleet (at least ``share_from`` survivors) every survivor computing the same
re-plan at once costs the fleet survivors x its CPU: 99 survivors of a 100-robot fleet on 2
cores re-planned 179-211 s after the death (docs/operations.md). There the lowest survivor
of the epoch (its *sharer*) computes it alone, in a process of its own (``routes_apart``),
and shares it (ReplanShare, with the digest of the reports); the others check it against
their own reports and walk it. A share that is unusable, or that has not come within
``share_wait`` (a safety net for a slow sharer: one that hangs for good is declared dead, a
new epoch with a new sharer), is computed locally after all: the same result, later. The
trade-off: a survivor of a crowded fleet
trusts the sharer's arithmetic (its inputs and the cover it promises are checked, the
routes' lengths are not); the fleet's robots are authenticated (docs/security.md).
"""

from __future__ import annotations

import hashlib
from collections.abc import Collection, Mapping
from dataclasses import dataclass

import numpy as np

from agent.offline.apart import computed_apart, shared_by_one
from bus import keys
from bus.drops import DropCounter
from bus.messages import ReplanReport, ReplanShare, unpack_covered, unpack_routes
from planner.offline.rebalance import Replan, Survivor, plan_order, rebalance
from planner.types import BoolArray, Cycle, IntArray, Plan

# Survivors from which one computes the re-plan for all: below, computing it is cheaper than
# waiting for a message (0.3-0.8 s of CPU at most 12 survivors, docs/balanced.md).
SHARE_FROM = 13
# On a large map fewer survivors share (agent.offline.apart.shared_by_one): 11 survivors
# each computing a 7.2 s re-plan of 40 392 sub-cells on 2 cores re-planned 84-90 s after the
# death, their peers declaring five of them dead meanwhile (2026-12-06).
# How long a survivor waits for the sharer's re-plan before computing it itself. The sharer
# computes it among the fleet's other work, which in a crowd starves it: 100 agents on 2
# cores overload them with their own heartbeats and announcements, and the sharer took 194 s
# for a re-plan of 0.7 s of CPU. With 0.5 s and then 1.5 s per survivor the 99 survivors
# gave up before the share came and all computed it anyway, later still. A sharer that hangs
# for good is declared dead (a new epoch, a new sharer), so the wait is a safety net for a
# slow one, not the way a lost sharer is replaced.
SHARE_WAIT_MIN_S = 10.0
SHARE_WAIT_S_PER_SURVIVOR = 3.0
# ... and with the map: 7.2 s of CPU alone on 40 392 sub-cells (a third of this).
SHARE_WAIT_S_PER_SUB_CELL = 0.5e-3

Routes = Mapping[int, tuple[int, ...]]


def share_wait(survivors: int, sub_cells: int = 0) -> float:
    """Seconds a survivor waits for a shared re-plan of ``survivors`` survivors over a
    ``sub_cells`` cycle."""
    return max(SHARE_WAIT_MIN_S, SHARE_WAIT_S_PER_SURVIVOR * survivors,
               SHARE_WAIT_S_PER_SUB_CELL * sub_cells)


class ReplanBoard:
    """The latest ReplanReport of each robot flying ``plan``. Only the
    plan's robots (the agreed participants) take part in a re-plan: a robot that never
    announced its start has no section, and its death changes nothing."""

    def __init__(self, plan: Plan, drops: DropCounter, *, share_from: int = SHARE_FROM) -> None:
        self.cycle = plan.cycle
        self.members = tuple(sorted(rp.robot for rp in plan.robots))
        self.drops = drops
        self.rank = plan_order(plan)
        self.share_from = share_from
        self.reports: dict[int, ReplanReport] = {}
        self.shares: dict[tuple[int, ...], tuple[ReplanShare, dict[int, tuple[int, ...]]]] = {}

    def on_report(self, key: str, msg: ReplanReport) -> bool:
        """Keep ``msg`` if it makes sense; True when it is news."""
        if self.reports.get(msg.robot) == msg:
            # every survivor re-announces its report each period: in a crowd of 60 the
            # checks below of the same reports again were a third of a waiting agent's loop
            return False
        n = self.cycle.n
        parsed = keys.parse(key)
        problem = ""
        places = (msg.position, *msg.route)
        if msg.robot not in self.members or (parsed is not None and parsed.robot != msg.robot):
            problem = f"replan report of robot {msg.robot} (no member of the plan) on {key}"
        elif min(places) < 0 or max(places) >= n:
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

    def on_share(self, key: str, msg: ReplanShare) -> bool:
        """Keep a shared re-plan if it is well formed; True when it is news."""
        known = self.shares.get(msg.dead)
        if known is not None and known[0] == msg:
            return False  # re-announced each period: checked already
        n = self.cycle.n
        parsed = keys.parse(key)
        survivors = tuple(r for r in self.members if r not in msg.dead)
        problem = ""
        routes: list[list[int]] = []
        if msg.robot not in self.members or (parsed is not None and parsed.robot != msg.robot):
            problem = f"replan share of robot {msg.robot} (no member of the plan) on {key}"
        elif tuple(sorted(set(msg.dead))) != msg.dead or msg.robot in msg.dead \
                or msg.robots != survivors or len(msg.lengths) != len(survivors):
            problem = (f"replan share of robot {msg.robot}: routes of {list(msg.robots)} for "
                       f"dead {list(msg.dead)}, not of the survivors")
        else:
            try:
                routes = unpack_routes(msg.places, msg.lengths)
            except ValueError as error:
                problem = f"replan share of robot {msg.robot}: {error}"
            if not problem and not all(0 <= i < n for route in routes for i in route):
                problem = f"replan share of robot {msg.robot} names places off the {n}-cycle"
        if problem:
            self.drops.count("replan_share", "invalid", problem)
            return False
        self.shares[msg.dead] = (msg, {r: tuple(route) for r, route
                                       in zip(msg.robots, routes, strict=True)})
        return True

    def sharer(self, dead: tuple[int, ...]) -> int | None:
        """The survivor that computes epoch ``dead``'s re-plan for all of them, or None if
        each computes it (agent.offline.apart.shared_by_one)."""
        survivors = [r for r in self.members if r not in dead]
        shared = shared_by_one(len(survivors), self.cycle.n, self.share_from)
        return survivors[0] if survivors and shared else None

    def shared(self, inputs: ReplanInputs) -> Shared | None:
        """The re-plan shared for ``inputs``' epoch, if any: usable when it was made from
        the same reports (the digest) and covers what they leave uncovered, else with the
        problem (counted; the share is then forgotten)."""
        kept = self.shares.get(inputs.dead)
        if kept is None:
            return None
        msg, routes = kept
        problem = ""
        if msg.digest != inputs.digest:
            problem = f"was made from other reports (digest {msg.digest[:16]})"
        else:
            walked = inputs.covered.copy()
            for route in routes.values():
                walked[list(route)] = True
            if not walked.all():
                problem = f"leaves {int((~walked).sum())} sub-cells uncovered"
        if problem:
            self.drops.count("replan_share", "unusable", f"replan share of robot {msg.robot} "
                                                         f"for dead {list(msg.dead)} {problem}")
            del self.shares[inputs.dead]
            return Shared(msg.robot, {}, problem)
        return Shared(msg.robot, routes)

    def epoch(self, dead: Collection[int]) -> tuple[int, ...]:
        """The re-plan epoch of the robots known dead: the plan's robots among them."""
        return tuple(r for r in self.members if r in dead)

    def missing(self, dead: tuple[int, ...]) -> list[int]:
        """Members not in ``dead`` whose report for epoch ``dead`` is not here yet."""
        return [r for r in self.members if r not in dead
                and (r not in self.reports or self.reports[r].dead != dead)]

    def stops(self, dead: tuple[int, ...]) -> dict[int, tuple[int, float]]:
        """Where each robot of epoch ``dead`` reported to stand, and its simulated time then."""
        return {r: (report.position, report.sim_time) for r, report in self.reports.items()
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
        return ReplanInputs(dead, self.cycle, covered, survivors, self.rank,
                            digest.hexdigest())


@dataclass(frozen=True)
class Shared:
    """A re-plan shared by ``sender``: its routes, or why they cannot be walked."""

    sender: int
    routes: Routes
    problem: str = ""


@dataclass(frozen=True)
class ReplanInputs:
    """One epoch's re-plan inputs and the digest of the reports they came from."""

    dead: tuple[int, ...]
    cycle: Cycle
    covered: BoolArray
    survivors: tuple[Survivor, ...]
    rank: IntArray
    digest: str

    def solve(self) -> Replan:
        """The re-plan (pure; a second or more of CPU in a large fleet)."""
        return rebalance(self.cycle, self.covered, self.survivors, self.rank)

    def routes(self) -> dict[int, tuple[int, ...]]:
        """The re-plan's routes, by survivor in order."""
        replan = self.solve()
        return {r: replan.routes[r] for r in sorted(replan.routes)}


async def routes_apart(inputs: ReplanInputs) -> tuple[dict[int, tuple[int, ...]], str]:
    """``inputs.routes()`` computed in a process of its own, in a session of its own
    (agent.offline.apart; the note says why not). The sharer of a crowded fleet computes
    there: in a thread of its agent the re-plan waited for the interpreter lock while the
    agent answered its peers' messages and queries, and 0.9 s of CPU took 177 s with 59
    survivors on 2 cores."""
    return await computed_apart(ReplanInputs.routes, inputs)
