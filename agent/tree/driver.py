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

import argparse
import asyncio
import contextlib
import sys
import time
from dataclasses import dataclass

from agent.core.errors import MissionFailedError
from agent.core.lifecycle import AgentLife, run_agent
from agent.tree.barrier import judge_step
from bus import keys
from bus.announce import Announcer
from bus.argtypes import index, positive, positive_int
from bus.bridge import BoundedFifo, Bus
from bus.config import add_connection_arguments, settings_from_args
from bus.liveness import LivelinessService
from bus.messages import DeathNotice, EventKind, RobotEvent, RobotStatus
from bus.tree_messages import TreeReport
from planner.errors import PlannerError
from planner.treecover.team import TeamReplica
from planner.treecover.trees import tree_from_spec
from planner.treecover.types import Algo

DEFAULT_STEP_TIMEOUT = 10.0
DEFAULT_SETTLE = 1.0  # the longest a dead robot's last report may still be on its way
ASSEMBLY_POLL_S = 0.05
INBOX_BACKLOG = 65536  # a step delivers at most k x k reports


@dataclass(frozen=True)
class TreeAgentConfig:
    robot: int
    robots: int
    tree: str
    algo: Algo
    incarnation: int = 1
    step_timeout: float = DEFAULT_STEP_TIMEOUT
    settle: float = DEFAULT_SETTLE
    heartbeat_period: float = 0.2
    dead_after: float = 3.0
    announce_period: float = 1.0


class TreeAgent(AgentLife):
    """One robot: report, relay, gather, decide, move."""

    def __init__(self, config: TreeAgentConfig, replica: TeamReplica) -> None:
        self.config = config
        self.robot = config.robot
        self.incarnation = config.incarnation
        self.stop = asyncio.Event()
        self.error = ""
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
        self.bus = bus
        c = self.config
        self.liveness = LivelinessService(bus, self.robot, self.incarnation,
                                          heartbeat_period=c.heartbeat_period,
                                          timeout=c.dead_after, on_death=self._on_death)
        self.announcer = Announcer(bus, keys.state(bus.mission, self.robot),
                                   period=c.announce_period)
        bus.subscribe(keys.tree_inbox(bus.mission, self.robot), TreeReport, self._on_report,
                      BoundedFifo(INBOX_BACKLOG))
        bus.subscribe(keys.all_events(bus.mission), RobotEvent, self._on_event,
                      BoundedFifo(4096))

    def _status(self, state: str, message: str = "") -> None:
        # start (0, 0): every tree robot starts on the root; the digest names the splits,
        # which every robot computes for itself and which must agree
        status = RobotStatus(self.robot, self.incarnation, (0, 0), self.config.algo.value,
                             f"splits {self.splits_text}", state, message)
        self.announcer.set(keys.status(self.bus.mission, self.robot), status)

    def _event(self, kind: EventKind, subject: int | None = None, detail: str = "") -> None:
        self.bus.publish(keys.events(self.bus.mission, self.robot),
                         RobotEvent(self.robot, self.incarnation, kind, subject, detail))

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
        if report.robot == self.robot or not 0 <= report.robot < self.config.robots:
            return
        for robot in report.dead:
            if 0 <= robot < self.config.robots:
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
        c, r = self.config, self.replica
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
        peers = set(range(self.config.robots)) - {self.robot}
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(self.config.step_timeout):
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


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--id", type=index, required=True, metavar="I",
                        help="this robot's id, 0..K-1")
    parser.add_argument("--robots", type=positive_int, required=True, metavar="K",
                        help="team size")
    parser.add_argument("--tree", required=True, metavar="SPEC",
                        help="perfect:N=3,H=4 | general:... | office | FILE.tree (a-priori map)")
    parser.add_argument("--algo", choices=[a.value for a in Algo], default="cocta")
    parser.add_argument("--incarnation", type=positive_int, default=1, metavar="N")
    parser.add_argument("--step-timeout", type=positive, default=DEFAULT_STEP_TIMEOUT,
                        metavar="SECONDS",
                        help="longest wait for every report of one step (default %(default)s)")
    parser.add_argument("--settle", type=positive, default=DEFAULT_SETTLE, metavar="SECONDS",
                        help="how long a dead robot's last report may still be on its way "
                             "(default %(default)s)")
    parser.add_argument("--heartbeat-period", type=positive, default=0.2, metavar="SECONDS")
    parser.add_argument("--dead-after", type=positive, default=3.0, metavar="SECONDS",
                        help="a robot silent this long is declared dead (default %(default)s)")
    add_connection_arguments(parser)


def run(args: argparse.Namespace) -> int:
    if args.id >= args.robots:
        print(f"mstc tree-agent: error: --id {args.id} is not below --robots {args.robots}",
              file=sys.stderr)
        return 2
    config = TreeAgentConfig(robot=args.id, robots=args.robots, tree=args.tree,
                             algo=Algo(args.algo), incarnation=args.incarnation,
                             step_timeout=args.step_timeout, settle=args.settle,
                             heartbeat_period=args.heartbeat_period, dead_after=args.dead_after)
    replica = TeamReplica(tree_from_spec(args.tree), args.robots, config.algo)
    return run_agent(TreeAgent(config, replica), settings_from_args(args))
