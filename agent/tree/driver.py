"""``mstc tree-agent``: one robot of connected tree coverage (NCOCTA / COCTA) as a process.

Each step t the robot transmits its own report (its node at t) on its outbox, then waits until
it holds every robot's report for t. It hears only what the radio (``mstc radio``) delivers
from robots on the same or an adjacent node, so reports flood through the connected team: a
robot re-transmits each report of step t it hears, once, while it stands at its step-t node
(reports of a later step are kept and re-transmitted on entering that step, so every copy goes
out from where the radio expects it). With every report of t in hand it runs the team replica
(planner.treecover.team): the same ``decide`` as every other robot, hence the same moves, and
walks its own. The step after the team is done (all nodes visited, all robots on the root) it
reports once more, so everybody confirms the end, and leaves.

A robot that dies is removed by every survivor at the same step boundary, the first step whose
report from it never comes (agent.tree.barrier decides when that is known; the argument is in
docs/treecover.md), and the replica repairs the trail. Deaths are learnt from the liveliness
service (the infrastructure's view, not the radio's), from peers' ``stopped`` / ``fenced``
events and from the ``dead`` set of the reports. A report whose ``gone`` set differs from the
replica's, a report that disagrees with the replica, a stall, or a step not complete within
``--step-timeout`` end the mission with a MissionFailedError (exit 3), a status and a
``stopped`` event saying why.
"""

from __future__ import annotations

import asyncio
import contextlib
import time

from agent.core.config import AgentConfig
from agent.core.errors import MissionFailedError
from agent.core.lifecycle import AgentLife, run_agent
from agent.tree.barrier import judge_step
from agent.tree.options import TreeOptions
from bus import keys
from bus.bridge import BoundedFifo, Bus
from bus.config import ConnectionSettings
from bus.messages import DeathNotice, RobotEvent, RobotStatus, TreeReport
from planner.errors import PlannerError
from planner.treecover.team import TeamReplica
from planner.treecover.trees import tree_from_spec
from planner.treecover.types import Algo

ASSEMBLY_POLL_S = 0.05
INBOX_BACKLOG = 65536  # a step delivers at most k x k reports


class TreeAgent(AgentLife):
    """One robot: report, relay, gather, decide, move."""

    def __init__(self, config: AgentConfig, options: TreeOptions, replica: TeamReplica) -> None:
        super().__init__(config)
        self.options = options
        self.algo = Algo(config.algo)
        self.replica = replica
        self.step = -1
        self.heard: dict[int, dict[int, int]] = {}  # step -> robot -> node
        self.later: dict[int, list[TreeReport]] = {}  # heard before this robot got there
        self.lost: dict[int, str] = {}  # robots dead or stopped -> why
        self.lost_since: dict[int, float] = {}  # robots dead or stopped -> when we learnt it
        self.mismatched = 0  # reports from robots our replica has removed (ignored)
        self.arrived = asyncio.Event()
        # step -> robot -> the removals its report of that step carries
        self.gone_seen: dict[int, dict[int, tuple[tuple[int, int], ...]]] = {}
        self.sent = 0
        self.duplicates = 0
        self.splits_text = ",".join(map(str, replica.splits.heights)) or "none"

    # --- bus -------------------------------------------------------------------------------

    def _wire(self, bus: Bus) -> None:
        self.liveness = self._make_liveness(bus, self._on_death)
        self.announcer = self._make_announcer(bus)
        bus.subscribe(keys.tree_inbox(bus.mission, self.robot), TreeReport, self._on_report,
                      BoundedFifo(INBOX_BACKLOG))
        bus.subscribe(keys.all_events(bus.mission), RobotEvent, self._on_event,
                      BoundedFifo(4096))

    def _status(self, state: str, message: str = "") -> None:
        # start (0, 0): every tree robot starts on the root; the digest names the splits,
        # which every robot computes for itself and which must agree
        status = RobotStatus(self.robot, self.incarnation, (0, 0), self.algo.value,
                             f"splits {self.splits_text}", state, message)
        self.announcer.set(keys.status(self.bus.mission, self.robot), status)

    def _on_death(self, notice: DeathNotice) -> None:
        # a robot that leaves once it holds every report of the last step is no failure (its
        # last report may still be on its way); one that gives up says so in an event
        if notice.reason != "leaving":
            self._lose(notice.robot, f"declared dead ({notice.reason})")

    def _on_event(self, _key: str, event: RobotEvent) -> None:
        if event.robot != self.robot and event.kind in ("stopped", "fenced"):
            self._lose(event.robot, f"{event.kind}: {event.detail}")

    def _lose(self, robot: int, why: str) -> None:
        if robot == self.robot or robot in self.lost:
            return
        self.lost[robot] = why
        self.lost_since[robot] = time.monotonic()
        print(f"tree-agent {self.robot}: robot {robot} {why}", flush=True)
        self.arrived.set()

    def _transmit(self, report: TreeReport) -> None:
        self.bus.publish(keys.tree_outbox(self.bus.mission, self.robot), report)
        self.sent += 1

    def _relay(self, report: TreeReport) -> None:
        self._transmit(TreeReport(report.robot, report.incarnation, report.step, report.node,
                                  self.robot, report.gone, report.dead))

    def _on_report(self, _key: str, report: TreeReport) -> None:
        if report.robot == self.robot or not 0 <= report.robot < self.config.k:
            return
        for robot in report.dead:
            if 0 <= robot < self.config.k:
                self._lose(robot, f"dead according to robot {report.robot}")
        if report.step < self.step or report.robot in self.heard.get(report.step, {}):
            self.duplicates += 1
            return
        if not self.replica.alive[report.robot]:
            self.mismatched += 1  # removed at an earlier boundary: not part of the team
            return
        known = self.heard.setdefault(report.step, {})
        known[report.robot] = report.node
        self.gone_seen.setdefault(report.step, {})[report.robot] = report.gone
        if report.step == self.step:
            self._relay(report)
        else:
            self.later.setdefault(report.step, []).append(report)
        self.arrived.set()

    # --- mission ---------------------------------------------------------------------------

    def _enter(self, step: int, node: int) -> None:
        """Stand on ``node`` at ``step``: transmit our report first (the radio locates us by
        it), then what others reported for this step before we got here."""
        self.heard.pop(step - 1, None)
        self.gone_seen.pop(step - 1, None)
        self.step = step
        self.heard.setdefault(step, {})[self.robot] = node
        gone = tuple(sorted(self.replica.removed.items()))
        self._transmit(TreeReport(self.robot, self.incarnation, step, node, self.robot, gone,
                                  tuple(sorted(self.lost))))
        for report in self.later.pop(step, []):
            self._relay(report)

    async def _gather(self, step: int) -> tuple[dict[int, int], tuple[int, ...]]:
        """The reports of ``step`` we can hear and the dead robots absent from it, once every
        live robot in hearing has reported and every death has settled."""
        known = self.heard[step]
        c, r = self.options, self.replica
        waiting: tuple[int, ...] = ()
        try:
            async with asyncio.timeout(c.step_timeout):
                while True:
                    verdict = judge_step(r.state.parent, r.positions, r.alive, self.robot,
                                         known.keys(), self.lost_since, time.monotonic(),
                                         c.settle)
                    waiting = verdict.waiting_for
                    if verdict.ready:
                        return dict(known), verdict.absent
                    self.arrived.clear()
                    with contextlib.suppress(TimeoutError):
                        async with asyncio.timeout(verdict.wake_in):
                            await self.arrived.wait()
        except TimeoutError:
            raise MissionFailedError(
                f"no report of step {step} from robot(s) {list(waiting)} within "
                f"{c.step_timeout:g} s") from None

    def _check(self, step: int, reported: dict[int, int]) -> None:
        """The reports agree with the replica: same robots removed, same nodes."""
        gone = tuple(sorted(self.replica.removed.items()))
        differ = sorted(robot for robot, theirs in self.gone_seen.get(step, {}).items()
                        if theirs != gone)
        if differ:
            theirs = self.gone_seen[step][differ[0]]
            raise MissionFailedError(
                f"step {step}: robot {differ[0]} removed (robot, step) {list(theirs)}, robot "
                f"{self.robot}'s replica {list(gone)}: the replicas have diverged")
        wrong = self.replica.disagreeing(reported)
        if wrong:
            raise MissionFailedError(
                f"step {step}: robot(s) {wrong} are not where robot {self.robot}'s replica "
                "has them")

    async def _assemble(self) -> None:
        """Wait, at most a step timeout, until the liveliness service knows every peer. A
        robot killed right after its first report might otherwise die before anyone saw its
        token, and an unknown robot is never declared dead."""
        peers = set(range(self.config.k)) - {self.robot}
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(self.options.step_timeout):
                while not peers <= self.liveness.detector.alive().keys() | self.lost.keys():
                    await asyncio.sleep(ASSEMBLY_POLL_S)

    async def _mission(self) -> None:
        self._status("covering")
        await self._assemble()
        started = time.monotonic()
        node = 0
        while True:
            self._enter(self.replica.step, node)
            reported, absent = await self._gather(self.replica.step)
            self._check(self.replica.step, reported)
            if absent:
                print(f"tree-agent {self.robot}: step {self.replica.step}: removing robot(s) "
                      f"{list(absent)} (no report of this step)", flush=True)
                self.replica.remove(absent)
            if self.replica.done():
                break
            try:
                node = self.replica.advance()[self.robot]
            except PlannerError as error:
                raise MissionFailedError(str(error)) from error
        summary = (f"coverage time {self.replica.step} steps, sent {self.sent}, "
                   f"duplicates {self.duplicates}, removed {sorted(self.replica.removed)}, "
                   f"ignored from removed robots {self.mismatched}, "
                   f"{time.monotonic() - started:.2f} s")
        print(f"tree-agent {self.robot}: done: {summary}", flush=True)
        self._status("done", summary)
        self._event("completed", detail=summary)


def drive(config: AgentConfig, options: TreeOptions, settings: ConnectionSettings) -> int:
    """Run one tree coverage robot to its end; the process exit code (agent/main.py)."""
    replica = TeamReplica(tree_from_spec(options.tree), config.k, Algo(config.algo))
    return run_agent(TreeAgent(config, options, replica), settings)
