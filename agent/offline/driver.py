"""The offline agent (``mstc agent --algo nb|bt|opt|balanced``): one robot's life from start-up to
leaving, in one asyncio TaskGroup.

Life cycle: read the start pose from the body, announce it (RobotStatus), gather every
robot's start, compute the plan, announce its digest and compare the others', drive the plan
(OfflineRunner), announce completion, linger, leave. Beside the mission run the liveness
service (token, heartbeats, failure detector), the announcer (re-publishes status, known
deaths and the mission verdict; answers state queries) and three watchers that end the group
with a specific exception: own death notice (FencedError), SIGTERM/SIGINT (LeaveRequested),
a peer's "failed" verdict (MissionFailedError). The process frame is agent.core.lifecycle's
and the gather agent.core.gather's, shared with the other families; this module adds the
offline mission and the third watcher.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Collection, Coroutine, Mapping, Sequence
from concurrent.futures.process import BrokenProcessPool
from typing import Any

from agent.core.config import AgentConfig
from agent.core.errors import AgentError, DigestMismatchError, MissionFailedError
from agent.core.gather import BodyAgent
from agent.core.hw_link import HwLink
from agent.core.lifecycle import run_agent
from agent.offline.apart import apart_from, computed_apart
from agent.offline.bodies import Bodies
from agent.offline.hardware import Hardware
from agent.offline.options import OfflineOptions
from agent.offline.peers import PeerTable
from agent.offline.plan import fleet_plan, robot_machine
from agent.offline.planshare import (
    UnusableShareError,
    plan_inputs,
    plan_of,
    share_of,
    share_wait,
    sharer,
    unshared,
)
from agent.offline.replan import ReplanBoard
from agent.offline.runner import OfflineRunner
from bus import keys
from bus.bridge import BoundedFifo, Bus, LatestWins, Received
from bus.codec import encode
from bus.config import ConnectionSettings
from bus.errors import EncodeError
from bus.liveness import HeartbeatInfo
from bus.messages import (
    AgentState,
    DeathNotice,
    Heartbeat,
    MissionState,
    MissionStatus,
    PlanShare,
    Progress,
    ReplanReport,
    ReplanShare,
    RobotEvent,
    RobotStatus,
    pack_covered,
)
from planner.digest import plan_digest
from planner.errors import PlannerError
from planner.grid import work_area
from planner.maps import resolve_world
from planner.types import Plan

_log = logging.getLogger("mstc.agent")
PULL_ROBOTS = 25


def next_in_turn(peers: Sequence[int], turn: int, count: int) -> tuple[list[int], int]:
    """The ``count`` robots of ``peers`` from position ``turn`` on (wrapping round; all of them
    if they are fewer), and the position to start from next time."""
    if len(peers) <= count:
        return list(peers), 0
    start = turn % len(peers)
    return [*peers[start:], *peers[:start]][:count], start + count


def pull_period(announce_period: float, k: int) -> float:
    """How often a robot pulls robots' state as a backstop for lost messages: once per
    announce period, and in a big fleet once per k / PULL_ROBOTS periods. Beyond PULL_ROBOTS
    robots a robot that is driving asks PULL_ROBOTS of them at a time (``OfflineAgent.in_turn``)
    and one waiting for re-plan reports only those whose report it lacks (``each``): a
    100-robot fleet whose survivors all pulled everyone's state while they waited for a
    re-plan spent a third of each agent's CPU answering those queries (py-spy, 2026-12-05).
    Every pull asks every robot for its state (coverage included), so the fleet's pulls grow
    with k squared: 60 robots pulling on every status heard never agreed within 100 s, and
    60 robots whose sections were done pulling every announce period (1.8 s) kept the others
    from moving once the router no longer held the traffic back."""
    return announce_period * max(1.0, k / PULL_ROBOTS)

STATE_KINDS = (RobotStatus, DeathNotice, MissionStatus, AgentState, RobotEvent, Progress,
               ReplanReport, ReplanShare, PlanShare)


class OfflineAgent(BodyAgent):
    """One robot. ``await agent.run(settings)`` returns the process exit code."""

    END_PRIORITY = (*BodyAgent.END_PRIORITY, PlannerError)

    def __init__(self, config: AgentConfig, options: OfflineOptions) -> None:
        super().__init__(config)
        self.options = options
        self.grid = resolve_world(options.world, options.cell_size)
        self.phase = "starting"
        self.digest = ""
        self.plan: Plan | None = None
        self.runner: OfflineRunner | None = None
        self.board: ReplanBoard | None = None
        self.bodies: Bodies | None = None
        self._pulled = -float("inf")  # self.now() of the last pull while gathering
        self._turn = 0  # where the next crowd pull in turn starts (next_in_turn)
        self._plan_shares: dict[int, PlanShare] = {}  # the latest first plan shared, by sharer

    # --- plumbing -------------------------------------------------------------------------

    def _wire(self, bus: Bus) -> None:
        m = bus.mission
        self.peers = PeerTable(self.robot, self.config.k, bus.drops)
        self.hardware = Hardware(bus, self.robot, self.incarnation,
                                 timeout=self.config.hw_timeout)
        self.liveness = self._make_liveness(bus, self._on_death, self._heartbeat_info,
                                            self._on_heartbeat)
        self.announcer = self._make_announcer(bus, self.state_message)
        bus.subscribe(keys.all_statuses(m), RobotStatus, self.peers.on_status,
                      BoundedFifo(4096))
        bus.subscribe(keys.all_progress(m), Progress, self._on_progress, BoundedFifo(65536))
        bus.subscribe(keys.mission_status(m), MissionStatus, self.peers.on_mission,
                      LatestWins())
        bus.subscribe(keys.all_plan_shares(m), PlanShare, self._on_plan_share, BoundedFifo(64))
        if self.options.recovery == "rebalance":
            bus.subscribe(keys.all_replans(m), ReplanReport, self._on_replan_report,
                          BoundedFifo(4096))
            bus.subscribe(keys.all_replan_shares(m), ReplanShare, self._on_replan_share,
                          BoundedFifo(256))

    def _on_plan_share(self, key: str, msg: PlanShare) -> None:
        parsed = keys.parse(key)
        if parsed is not None and parsed.robot != msg.robot:
            self.bus.drops.count("plan_share", "invalid",
                                 f"plan share of robot {msg.robot} on {key}")
            return
        if self._plan_shares.get(msg.robot) != msg:
            self._plan_shares[msg.robot] = msg
            self.peers.changed.set()

    def _on_replan_report(self, key: str, msg: ReplanReport) -> None:
        if self.board is not None and self.board.on_report(key, msg):
            self.peers.changed.set()

    def _on_replan_share(self, key: str, msg: ReplanShare) -> None:
        if self.board is not None and self.board.on_share(key, msg):
            self.peers.changed.set()

    def _heartbeat_info(self) -> HeartbeatInfo:
        return HeartbeatInfo(pose=self.hardware.state.pose, state=self._phase(),
                             sim_time=self.hardware.state.sim_time)

    def _phase(self) -> str:
        return self.runner.phase if self.runner is not None and self.phase == "driving" \
            else self.phase

    def _on_progress(self, key: str, msg: Progress) -> None:
        if msg.robot != self.robot:
            self.peers.on_progress(key, msg)
            if self.bodies is not None and self.bodies.on_progress(
                    msg.robot, msg.seq, self.bodies.cycle.position((msg.cell[0], msg.cell[1])),
                    msg.sim_time):
                self.peers.changed.set()  # a body moved: a robot waiting on it decides again

    def _on_heartbeat(self, hb: Heartbeat) -> None:
        # the heartbeats' poses put right a body whose Progress was lost (Bodies.on_pose)
        if hb.robot != self.robot and hb.pose is not None and self.bodies is not None \
                and self.bodies.on_pose(hb.robot, self.bodies.cycle.position(
                    (hb.pose[0], hb.pose[1])), hb.sim_time):
            self.peers.changed.set()

    def _on_death(self, notice: DeathNotice) -> None:
        # Deaths are durable facts: re-announce them so a restarted router loses none.
        self.announcer.set(keys.death(self.bus.mission, notice.robot), notice, publish=False)
        self.peers.on_death(notice)

    def state_message(self) -> AgentState:
        machine = self.peers.machine
        drops = {f"{kind}.{why}": n for (kind, why), n in self.bus.drops.snapshot().items()}
        return AgentState(
            robot=self.robot, incarnation=self.incarnation, state=self._phase(),
            moves=self.runner.moves if self.runner else 0,
            n=machine.cycle.n if machine else 0,
            covered=pack_covered(machine.covered) if machine else b"",
            dead=tuple(sorted(self.peers.dead)),
            took_over=tuple(self.runner.took_over) if self.runner else (), drops=drops,
            tree_kind=self.options.tree, seed=self.config.seed)

    def _status(self, state: str, message: str = "") -> None:
        if self.start is None:
            return
        drops = self.bus.drops.total()
        text = message or (f"drops {drops}" if drops else "")
        status = RobotStatus(self.robot, self.incarnation, self.start, self.config.algo,
                             self.digest, state, text, self._roster_wire(state))
        self.peers.on_status(keys.status(self.bus.mission, self.robot), status)
        self.announcer.set(keys.status(self.bus.mission, self.robot), status)

    def _mission_status(self, state: MissionState, message: str,
                        **summary: int | float | str) -> None:
        status = MissionStatus(state, message, dict(summary))
        self.announcer.set(keys.mission_status(self.bus.mission), status)
        self.peers.on_mission(keys.mission_status(self.bus.mission), status)

    async def refresh(self) -> None:
        """Pull every robot's re-learnable state (coverage, deaths, statuses)."""
        await self._pull(keys.all_states(self.bus.mission))

    async def pull(self, robot: int) -> None:
        """Pull one robot's re-learnable state: a survivor waiting for the sharer's re-plan
        asks the sharer only (every robot's, in a crowd, is what starves the sharer)."""
        await self._pull(keys.state(self.bus.mission, robot))

    async def in_turn(self) -> None:
        """A crowd's watcher's backstop pull: PULL_ROBOTS live robots, the next ones in turn
        (``next_in_turn``), so every robot is asked within k / PULL_ROBOTS pulls. Every robot's
        state carries all the coverage it knows, so a few answer for most of the fleet."""
        peers = [r for r in self.participants() if r != self.robot and r not in self.peers.dead]
        chosen, self._turn = next_in_turn(peers, self._turn, PULL_ROBOTS)
        await self.each(chosen)

    async def each(self, robots: Sequence[int]) -> None:
        """Pull the state of each of ``robots``, one query each, side by side."""
        await asyncio.gather(*(self.pull(robot) for robot in robots))

    async def _pull(self, key: str) -> None:
        replies: list[Received[Any]] = await self.bus.query(
            key, None, STATE_KINDS, timeout=min(1.0, self.config.announce_period * 2))
        for rx in replies:
            msg = rx.msg
            if isinstance(msg, RobotStatus):
                self.peers.on_status(keys.status(self.bus.mission, msg.robot), msg)
            elif isinstance(msg, AgentState) and msg.robot != self.robot:
                self.peers.on_state(rx.key, msg)
            elif isinstance(msg, DeathNotice):
                # the same checks as a notice heard live: a known detector, a real life
                self.liveness.accept_notice(msg)
            elif isinstance(msg, MissionStatus):
                self.peers.on_mission(rx.key, msg)
            elif isinstance(msg, ReplanReport):
                self._on_replan_report(keys.replan(self.bus.mission, msg.robot), msg)
            elif isinstance(msg, ReplanShare):
                self._on_replan_share(keys.replan_share(self.bus.mission, msg.robot), msg)
            elif isinstance(msg, PlanShare):
                self._on_plan_share(keys.plan_share(self.bus.mission, msg.robot), msg)

    # --- the mission ----------------------------------------------------------------------

    def _link(self) -> HwLink:
        return self.hardware.link

    def _peer_statuses(self) -> Mapping[int, RobotStatus]:
        return self.peers.statuses

    def _dead_robots(self) -> Collection[int]:
        return self.peers.dead

    async def _wait_news(self, missing: Sequence[int] = ()) -> None:
        # Pull what may have been lost at most once per pull_period: news wakes this wait
        # many times a second; statuses and deaths are re-announced meanwhile anyway. In a
        # crowd, a wait for some robots (their plan digests) asks those alone: 100 robots
        # that pulled every robot's state while they waited for the digests took 27 s to
        # hear them all (2026-12-05).
        every = pull_period(self.config.announce_period, self.config.k)
        if self.now() - self._pulled >= every:
            self._pulled = self.now()
            if missing and self.config.k > PULL_ROBOTS:
                await self.each(missing)
            else:
                await self.refresh()
        await self.peers.wait_news(self.config.announce_period)

    def _gathering(self) -> None:
        self.phase = "gathering"

    async def _gather(self) -> list[tuple[int, int]]:
        """The agreed participants' starts, in robot-id order."""
        await self._gather_starts()
        assert self.roster is not None
        return [self.roster[r] for r in sorted(self.roster)]

    def _plan_args(self, starts: list[tuple[int, int]]) -> tuple[Any, ...]:
        return (self.grid, starts, self.participants(), self.config.algo, self.options.tree,
                self.config.seed)

    async def _first_plan(self, starts: list[tuple[int, int]]) -> tuple[Plan, str]:
        """The participants' plan and how it was had (for the log): computed here, or in a
        crowd computed by the lowest participant and shared (agent.offline.planshare)."""
        ids = self.participants()
        sub_cells = work_area(self.grid, starts).n
        first = sharer(ids, self.options.plan_share_from, sub_cells)
        if first is None:
            # off the loop, as a re-plan is (agent/offline/runner.py): a balanced plan took
            # 3.4 s on a host busy with three chaos trials, no heartbeat went out meanwhile,
            # and a peer declared this robot dead (chaos seed 63, trial 71); on a large
            # map in a process of its own (agent.offline.apart.apart_from)
            return await self._plan_here(starts, sub_cells)
        inputs = plan_inputs(self.grid, ids, starts, self.config.algo, self.options.tree,
                             self.config.seed)
        if first == self.robot:
            return await self._share_plan(starts, inputs)
        wait = share_wait(len(ids), sub_cells)
        deadline = self.now() + wait
        self.phase = f"waiting for robot {first}'s plan"
        while True:
            msg = self._plan_shares.get(first)
            why = ""
            if msg is not None and msg.inputs != inputs:
                # the digests will tell the fleet which inputs differ: compare them now
                why = f"robot {first}'s share was made from other inputs"
            elif msg is not None:
                try:
                    # in a thread: the checks walk every sub-cell (0.2 s at 47 000)
                    plan = await asyncio.to_thread(plan_of, msg, work_area(self.grid, starts),
                                                   ids, self.config.algo)
                    return plan, f", shared by robot {first}"
                except UnusableShareError as error:
                    self.bus.drops.count("plan_share", "unusable", f"robot {first}'s: {error}")
                    why = f"robot {first}'s share is unusable: {error}"
            elif first in self.peers.dead:
                why = f"robot {first} died"
            elif self.now() >= deadline:
                why = f"robot {first}'s not heard in {wait:.0f} s"
            if why:
                self.phase = "planning"
                plan, where = await self._plan_here(starts, sub_cells)
                return plan, f", computed here: {why}{where}"
            # the sharer re-announces it every period; the backstop for a lost one asks the
            # sharer alone (every robot's state, in a crowd, is what starves the sharer)
            if self.now() - self._pulled >= pull_period(self.config.announce_period,
                                                        self.config.k):
                self._pulled = self.now()
                await self.pull(first)
            await self.peers.wait_news(self.config.announce_period)

    async def _plan_here(self, starts: list[tuple[int, int]], sub_cells: int
                         ) -> tuple[Plan, str]:
        """The plan computed by this robot for itself: in a process of its own for a large
        work-area (agent.offline.apart.apart_from), else in a thread."""
        if apart_from(sub_cells):
            return await self._plan_apart(starts)
        return await asyncio.to_thread(fleet_plan, *self._plan_args(starts)), ""

    async def _plan_apart(self, starts: list[tuple[int, int]]) -> tuple[Plan, str]:
        """The plan computed in a process of its own, and a note when it was not."""
        try:
            return await computed_apart(fleet_plan, *self._plan_args(starts))
        except (OSError, BrokenProcessPool) as error:
            # no process to be had: the same plan in a thread, later in a crowd
            plan = await asyncio.to_thread(fleet_plan, *self._plan_args(starts))
            return plan, f" (computed in a thread: no process for it: {error})"

    async def _share_plan(self, starts: list[tuple[int, int]], inputs: str
                          ) -> tuple[Plan, str]:
        """The sharer's side: the plan computed in a process of its own, and announced."""
        plan, where = await self._plan_apart(starts)
        share = share_of(plan, self.robot, self.incarnation, inputs)
        try:
            encode(share, max_size=self.bus.max_payload)
        except EncodeError as error:
            share = unshared(self.robot, self.incarnation, inputs, str(error))
            where += f" (not shared: {error})"
        self.announcer.set(keys.plan_share(self.bus.mission, self.robot), share)
        return plan, f", shared with the fleet{where}"

    def _check_digests(self) -> None:
        members = set(self.participants())
        others = {r: s.plan_digest for r, s in self.peers.statuses.items()
                  if r in members and s.plan_digest and s.plan_digest != self.digest}
        if others:
            described = ", ".join(f"robot {r} has {d[:12]}" for r, d in sorted(others.items()))
            raise DigestMismatchError(
                f"plan digest mismatch: robot {self.robot} (this one) has {self.digest[:12]}, "
                f"{described}; check that every agent got the same --world, --algo, --tree, "
                f"--seed and --robots")

    async def _mission(self) -> None:
        starts = await self._gather()
        self.phase = "planning"
        try:
            self.plan, how = await self._first_plan(starts)
        except PlannerError as error:
            self._mission_status("failed", f"robot {self.robot} cannot plan: {error}")
            raise
        self.phase = "planning"
        self.digest = plan_digest(self.plan)
        mine = next(rp for rp in self.plan.robots if rp.robot == self.robot)
        self._say(f"plan {self.digest[:12]} makespan {self.plan.makespan} moves, mine "
                  f"{mine.steps}{how}")
        self._status("planned")
        self._check_digests()
        if self.config.k > PULL_ROBOTS:
            self._pulled = self.now()  # the digests are being announced now: pull later
        await self._until(lambda: self.peers.missing_digests(self.participants()),
                          "announce their plan digest",
                          self._check_digests)
        self._check_digests()
        # everyone has flown the shared plan's digest: no one needs the share any more
        self.announcer.remove(keys.plan_share(self.bus.mission, self.robot))
        rebalancing = self.options.recovery == "rebalance"
        machine = robot_machine(self.plan, self.config.algo, self.robot,
                                takeover=not rebalancing)
        self.peers.attach(machine)
        if rebalancing:
            self.board = ReplanBoard(self.plan, self.bus.drops,
                                     share_from=self.options.replan_share_from)
            self.bodies = Bodies.of_plan(self.plan, self.robot)
        self.runner = OfflineRunner(self.bus, self.hardware, self.peers, machine,
                                    self.incarnation, refresh=self.refresh, pull=self.pull,
                                    crowd=self if self.config.k > PULL_ROBOTS else None,
                                    refresh_period=pull_period(self.config.announce_period,
                                                               self.config.k),
                                    board=self.board, announce=self.announcer.set,
                                    quiet=self.announcer.quiet,
                                    bodies=self.bodies)
        self.phase = "driving"
        self._status("covering")
        self._say("driving")
        await self.runner.run()
        self.phase = "done"
        self._status("done")
        traffic = self.runner.traffic_detail()
        self._event("completed", detail=f"{self.runner.moves} moves"
                                        + (f", {traffic}" if traffic else ""))
        self._mission_status("complete", f"robot {self.robot} knows every sub-cell covered",
                             robot=self.robot, moves=self.runner.moves)
        self._say(f"completed after {self.runner.moves} moves")
        await asyncio.sleep(self.config.linger)

    # --- watchers -------------------------------------------------------------------------

    async def _watch_mission(self) -> None:
        while True:
            await self.peers.verdict.wait()
            mission = self.peers.mission
            if mission is not None and mission.state == "failed":
                raise MissionFailedError(f"mission failed: {mission.message}")
            self.peers.verdict.clear()

    def _watchers(self) -> list[Coroutine[Any, Any, None]]:
        return [*super()._watchers(), self._watch_mission()]

    def _ending_agent_error(self, error: AgentError) -> None:
        if isinstance(error, MissionFailedError) and (
                self.peers.mission is None or self.peers.mission.state != "failed"):
            self._mission_status("failed", str(error))


def drive(config: AgentConfig, options: OfflineOptions, settings: ConnectionSettings) -> int:
    """Run one offline robot to its end; the process exit code (agent/main.py)."""
    return run_agent(OfflineAgent(config, options), settings)
