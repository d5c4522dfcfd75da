"""``mstc agent --algo ormstc``: drive one robot's OrmstcMachine with simhw's body and the bus.

The machine (planner.ormstc) decides everything; this module carries its requests out, as
planner/ormstc/lockstep.py does in-process:

- ``Sense`` -> sonar commands (agent.ormstc.body.look: which sonar, turning first when the
  cell is behind, a look from the sub-cell beside for a half never seen; ``--sense-mode
  single`` or a simhw in one-at-a-time mode: one sonar per command; each step aside or back
  is published as a LookStep), ``Move`` -> turns and
  one forward step (a bump is ``MoveResult(ok=False)``),
  ``IsAlive`` -> the failure detector's verdict, ``Broadcast`` -> a bus message
  (agent.ormstc.wire), ``Done`` -> status "done" and a "completed" event.
- Peer messages and the liveness service's deaths become ``PeerMessage`` / ``PeerDied``;
  the machine is ticked with the monotonic clock in seconds (agent.ormstc.options says why).

Life cycle: the core's gather (agent.core.gather: read the pose, announce a status
"gathering" once subscribed, agree on the participants, so nobody's StartMsg is published
before a peer listens), run the machine; once it reports Done and every other
robot is done or dead, linger and leave.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Collection, Mapping, Sequence

from agent.core.config import AgentConfig
from agent.core.errors import HardwareError
from agent.core.gather import BodyAgent
from agent.core.hw_link import HwLink
from agent.core.lifecycle import run_agent
from agent.ormstc.body import Body
from agent.ormstc.looks import Looker, glance
from agent.ormstc.options import OrmstcOptions, rejoin_silence, resend_grace
from agent.ormstc.sensing import (
    HEADING_DELTA,
    SonarMap,
    cell_of,
    peer_may_be_in,
)
from agent.ormstc.wire import WIRE_TYPES, Inbound, Rejoin, TreeBook, key_for, to_wire
from bus import keys
from bus.bridge import BoundedFifo, Bus, LatestWins
from bus.codec import encode
from bus.config import ConnectionSettings
from bus.liveness import HeartbeatInfo
from bus.messages import (
    AgentState,
    DeathNotice,
    Heartbeat,
    LookStep,
    OrmstcWire,
    RobotStatus,
    SonarRays,
)
from planner.ormstc.conflicts import restate
from planner.ormstc.machine import OrmstcMachine
from planner.ormstc.streams import Resender
from planner.ormstc.types import (
    AliveResult,
    Broadcast,
    Cell,
    ClaimMsg,
    DeadRobotMsg,
    Event,
    IsAlive,
    Message,
    Move,
    MoveResult,
    PeerAck,
    PeerDied,
    PeerMessage,
    Request,
    Sense,
    SenseResult,
    StartMsg,
    SubCell,
    Tick,
)

STATIC_BUMPS = 3  # bumps into an obstacle (not a body) before the move is hopeless


class OrmstcAgent(BodyAgent):
    """One ORMSTC robot process. ``await agent.run(settings)`` returns the exit code."""

    def __init__(self, config: AgentConfig, options: OrmstcOptions) -> None:
        super().__init__(config)
        self.options = options
        self.news = asyncio.Event()
        self.machine: OrmstcMachine | None = None
        self.sonar = SonarMap()
        self.pending: list[Event] = []
        self.statuses: dict[int, RobotStatus] = {}
        self.dead: set[int] = set()
        self.peer_cells: dict[int, Cell] = {}  # last heartbeat pose of each peer
        self.state = "starting"
        self.sent = 0
        self.sent_bytes = 0
        self._static_bumps = 0
        self.book = TreeBook()
        self.log: list[OrmstcWire] = []  # what this life said, by seq - 1 (for resends)
        # a message a peer's heartbeat shows lacking is said again once older than this (not
        # merely in flight or unread: a loaded host reads its queue late), then backing off
        self.resender = Resender(config.incarnation, grace=resend_grace(config.heartbeat_period),
                                 cap=1.0)
        self.resent_bytes = 0
        self.broadcasts = 0  # the machine's Broadcasts published (its numbering of them)
        self.index_of_seq: list[int] = []  # per published seq: broadcasts published by then
        self._acks: dict[int, float] = {}
        # a peer silent this long was cut off: restate (docs/ormstc.md, "Router restarts")
        self.rejoin = Rejoin(silence=rejoin_silence(config.heartbeat_period, config.dead_after))

    # --- plumbing -------------------------------------------------------------------------

    def _wire(self, bus: Bus) -> None:
        c, m = self.config, bus.mission
        self.body = Body(bus, self.robot, c.incarnation, c.hw_timeout)
        self.looker = Looker(self.body, self.sonar, self._look_step)
        self.inbound = Inbound(self.robot, c.k, bus.drops)
        self.liveness = self._make_liveness(bus, self._on_death, self._heartbeat_info)
        self.announcer = self._make_announcer(bus, self.state_message)
        # Each claim, edge and completion is said once: recovered from the senders' caches
        # after a router restart or freeze instead of waiting for a silence (bus.recovery).
        bus.subscribe(keys.all_ormstc(m), WIRE_TYPES, self._on_ormstc, BoundedFifo(65536),
                      recover=True)
        bus.subscribe(keys.all_statuses(m), RobotStatus, self._on_status, LatestWins())
        bus.subscribe(keys.all_heartbeats(m), Heartbeat, self._on_heartbeat, LatestWins())
        bus.subscribe(keys.all_sonar_rays(m), SonarRays, self._on_rays, BoundedFifo(4096))

    def _heartbeat_info(self) -> HeartbeatInfo:
        return HeartbeatInfo(pose=self.body.pose, state=self.state, said=self.sent,
                             heard=self.inbound.streams.heard())

    def _wake(self, event: Event | None = None) -> None:
        if event is not None:
            self.pending.append(event)
        self.news.set()

    def _on_ormstc(self, key: str, wire: OrmstcWire) -> None:
        claims = False
        for item, msg in self.inbound.accept(key, wire, self.now()):
            self.book.heard(item)
            self._wake(PeerMessage(item.robot, msg))
            claims = claims or msg.__class__ is ClaimMsg
        self._ack(wire.robot)
        if claims:  # the claimant decides once our heartbeat says we heard it: say so now
            self.liveness.beat_soon()

    def _ack(self, robot: int, upto: float | None = None) -> None:
        """Tell the machine how many of its broadcasts a peer acknowledged, counting only
        acknowledgements all of whose preceding messages are in (planner.ormstc.streams)."""
        if upto is None:
            taken = min(self.inbound.streams.acked(robot), len(self.index_of_seq))
            upto = self.index_of_seq[taken - 1] if taken > 0 else 0
        if upto > self._acks.get(robot, 0):
            self._acks[robot] = upto
            self._wake(PeerAck(robot, upto))

    def _on_rays(self, key: str, rays: SonarRays) -> None:
        if rays.robot != self.robot:
            self.sonar.hear(rays.rays)

    def _tell_rays(self) -> None:
        """Publish the rays read since the last time: peers look from beside less often."""
        rays = self.sonar.told()
        if rays:
            self.bus.publish(keys.sonar_rays(self.bus.mission, self.robot),
                             SonarRays(self.robot, self.config.incarnation, rays))

    def _on_status(self, key: str, status: RobotStatus) -> None:
        if 0 <= status.robot < self.config.k and status.robot != self.robot:
            self.statuses[status.robot] = status
            self._wake()

    def _on_heartbeat(self, key: str, hb: Heartbeat) -> None:
        if hb.pose is not None and hb.robot != self.robot:
            self.peer_cells[hb.robot] = cell_of((hb.pose[0], hb.pose[1]))
        if hb.robot == self.robot or not 0 <= hb.robot < self.config.k:
            return
        now = self.now()
        if self.rejoin.heard(hb.robot, now):
            self._wake()
        mine = [(life, taken) for robot, life, taken in hb.heard if robot == self.robot]
        acked = next((taken for life, taken in mine if life == self.config.incarnation), None)
        self.inbound.heartbeat(hb.robot, hb.incarnation, hb.said, now, acked)
        self._ack(hb.robot)
        for life, taken in mine:
            for seq in self.resender.lacking(life, taken, now):
                self._resend(self.log[seq - 1])

    def _resend(self, wire: OrmstcWire) -> None:
        """Say a message again with its own number: a peer lacks it (lost on the way)."""
        self.resent_bytes += len(encode(wire))
        self.bus.publish(key_for(self.bus.mission, wire), wire)

    def _on_death(self, notice: DeathNotice) -> None:
        robot = notice.robot
        if robot in self.dead or not 0 <= robot < self.config.k:
            return
        self.dead.add(robot)
        self.announcer.set(keys.death(self.bus.mission, robot), notice, publish=False)
        self._ack(robot, float("inf"))  # nothing more to wait for from it
        status = self.statuses.get(robot)
        if status is not None and status.state == "done":
            return  # it left after the mission was over for it: nothing to take over
        self._wake(PeerDied(robot))

    def state_message(self) -> AgentState:
        """The state reply: what a late joiner cannot hear again (tree edges, claims)."""
        machine = self.machine
        drops = {f"{kind}.{why}": n for (kind, why), n in self.bus.drops.snapshot().items()}
        tree = self.book.tree
        if machine is not None:  # minus cells handed over in a conflict (ormstc/conflicts.py)
            tree = [edge for edge in tree if edge[1] in machine.mine
                    and edge[1] not in machine.ceded]
        return AgentState(
            robot=self.robot, incarnation=self.config.incarnation, state=self.state,
            moves=machine.moves if machine else 0, n=0, covered=b"",
            dead=tuple(sorted(self.dead)), took_over=(), drops=drops,
            tree=tuple(tree), claims=tuple(self.book.claims))

    def _status(self, state: str, message: str = "") -> None:
        self.state = state
        if self.start is not None:
            self.announcer.set(keys.status(self.bus.mission, self.robot), RobotStatus(
                self.robot, self.config.incarnation, self.start, self.config.algo, "", state,
                message, self._roster_wire(state)))

    def _broadcast(self, request: Broadcast) -> None:
        self.broadcasts += 1
        self.book.sent(self._publish(request.message))
        if isinstance(request.message, DeadRobotMsg):  # for monitors and mstc up's summary
            self._event("takeover_started", request.message.dead, "its cells are free again")

    def _publish(self, message: Message) -> OrmstcWire:
        self.sent += 1
        wire = to_wire(message, self.config.incarnation, self.sent)
        self.log.append(wire)
        self.index_of_seq.append(self.broadcasts)
        self.resender.said(self.sent, self.now())
        self.sent_bytes += len(encode(wire))
        self.bus.publish(key_for(self.bus.mission, wire), wire)
        return wire

    def _restate(self, machine: OrmstcMachine) -> None:
        """Say again what peers must know of this robot and may have lost (a restart)."""
        said = restate(machine)
        for message in said:
            self._publish(message)
        self._say(f"restated {len(said)} messages (peers were cut off)")

    def may_hold_body(self, cell: Cell) -> bool:
        """A robot body can stand in ``cell`` (see agent.ormstc.sensing)."""
        know = self.machine.know if self.machine is not None else None
        return (know is not None and (cell in know.owners or cell in know.claims.pending)) \
            or cell in self.peer_cells.values()

    # --- requests -------------------------------------------------------------------------

    def peer_may_be_in(self, cell: Cell) -> bool:
        """A peer's body can stand in ``cell``, a cell this robot owns (sensing.peer_may_be_in)."""
        know = self.machine.know if self.machine is not None else None
        return peer_may_be_in(cell, self.robot, know, self.peer_cells.values())

    async def sense(self, request: Sense) -> SenseResult:
        return await self.looker.sense(request, self.options.sense_mode, self.may_hold_body,
                                       self.peer_may_be_in)

    def _look_step(self, seq: int, cell: SubCell) -> None:
        """A step made only to sense, published so that a report does not take it for a
        coverage revisit (LookStep)."""
        self.bus.publish(keys.look_steps(self.bus.mission, self.robot),
                         LookStep(self.robot, self.config.incarnation, seq, cell))

    async def move(self, to: SubCell) -> bool:
        if await self.looker.settle(to):
            return True  # the last look's step aside went there: the rays are read already
        assert self.body.pose is not None
        delta = (to[0] - self.body.pose[0], to[1] - self.body.pose[1])
        await self.body.face(HEADING_DELTA.index(delta))
        reply = await self.body.step()
        if reply.status == "ok":
            self._static_bumps = 0
            self.looker.walked(to)  # the step back out of a cell given up is a look step
            # rays from every sub-cell walked spare looks from beside (agent.ormstc.looks)
            await glance(self.body, self.sonar, self.may_hold_body)
            return True
        if reply.status != "bumped":
            raise HardwareError(f"robot {self.robot}: forward answered {reply.status}: "
                                f"{reply.message}")
        # A body moves on; an obstacle does not: one the sonar never saw (a thin ray sees
        # half of a neighbouring cell) makes this move hopeless.
        self._static_bumps = 0 if "body" in reply.message else self._static_bumps + 1
        if self._static_bumps >= STATIC_BUMPS:
            raise HardwareError(f"robot {self.robot}: {reply.message} {STATIC_BUMPS} times; "
                                "an obstacle the sonar could not see is inside a cell it "
                                "covers (see docs/ormstc.md, sensing)")
        return False

    def alive(self, robot: int) -> bool:
        return robot not in self.dead

    # --- the mission ----------------------------------------------------------------------

    def _link(self) -> HwLink:
        return self.body.link

    async def _wait_news(self, missing: Sequence[int] = ()) -> None:
        del missing  # peers' news comes on its own here: nothing is pulled
        self.news.clear()
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(self.config.announce_period):
                await self.news.wait()

    def _peer_statuses(self) -> Mapping[int, RobotStatus]:
        return self.statuses

    def _dead_robots(self) -> Collection[int]:
        return self.dead

    def _others_finished(self) -> bool:
        return all(r == self.robot or r in self.dead
                   or (r in self.statuses and self.statuses[r].state == "done")
                   for r in self.participants())

    async def _drive(self, machine: OrmstcMachine) -> None:
        answer: Event | None = None
        reported = False  # the last Done state announced
        settled_since: float | None = None
        while True:
            if self.rejoin.take(self.now()):
                self._restate(machine)
            events: list[Event] = [Tick(self.now()), *self.pending]
            self.pending = []
            if answer is not None:
                events.append(answer)
                answer = None
            for request in machine.step(events):
                answer = await self._carry_out(request) or answer
            if reported != machine.done_sent:  # Done, or taken back by a withdrawal
                reported = machine.done_sent
                self._finished(reported, machine)
            if answer is not None or self.pending:
                continue
            now = self.now()
            if reported and self._others_finished():
                settled_since = now if settled_since is None else settled_since
                if now - settled_since >= self.config.linger:
                    return
            else:
                settled_since = None
            wake = min(machine.wake_time() or now, self.rejoin.next_due() or float("inf"))
            delay = min(wake - now, self.config.announce_period)
            if delay > 0:
                self.news.clear()
                with contextlib.suppress(TimeoutError):
                    async with asyncio.timeout(delay):
                        await self.news.wait()

    async def _carry_out(self, request: Request) -> Event | None:
        """Do one request; the answer the machine waits for, if it waits for one."""
        if isinstance(request, Broadcast):
            self._broadcast(request)
        elif isinstance(request, IsAlive):
            return AliveResult(request.robot, self.alive(request.robot))
        elif isinstance(request, Sense):
            result = await self.sense(request)
            self._tell_rays()
            return result
        elif isinstance(request, Move):
            moved = await self.move(request.to)
            self._tell_rays()
            return MoveResult(moved)
        return None  # Done: read from machine.done_sent, which a withdrawal resets

    def _finished(self, done: bool, machine: OrmstcMachine) -> None:
        detail = (f"{machine.moves} moves, {len(machine.mine)} cells, {self.sent} messages, "
                  f"{self.sent_bytes} bytes, {self.resender.resent} resent "
                  f"({self.resent_bytes} bytes), {machine.ack_waits} claims waited for "
                  f"acknowledgements, {self.sonar.steps} steps to look "
                  f"({self.sonar.beside_looks} looks from beside), "
                  f"{machine.given_up} cells given up from inside, "
                  f"{self.sonar.glance_readings} readings after moves")
        if done:
            self._status("done")
            self._event("completed", detail=detail)
            self._say(f"done: {detail}")
        else:
            self._status("covering")
            self._event("completion_withdrawn")
            self._say("completion withdrawn")

    async def _mission(self) -> None:
        start = await self._gather_starts()
        self.machine = OrmstcMachine(self.options.machine(self.config, start))
        # Every participant's start is in the agreed roster: a StartMsg lost on the wire must
        # not leave the machine waiting for it (nor for a silence to trigger a restatement).
        assert self.roster is not None
        for robot, sub in sorted(self.roster.items()):
            if robot != self.robot:
                self.pending.append(PeerMessage(robot, StartMsg(robot, sub)))
        for robot in range(self.config.k):  # non-participants say nothing to wait for
            if robot not in self.roster or robot in self.dead:
                self._ack(robot, float("inf"))
        self._status("covering")
        self._event("started")
        self._say("driving")
        await self._drive(self.machine)
        m = self.machine
        self._say(f"completed after {m.moves} moves; {len(m.conflicts)} claim conflicts "
                  f"({m.cut} cells handed over), {self.rejoin.count} restatements, "
                  f"{self.inbound.repeats} repeats heard, {self.inbound.gaps} missing "
                  f"messages of peers seen, {self.inbound.streams.duplicates} duplicates, "
                  f"{self.resender.resent} resent, {m.ack_waits} claims waited for "
                  "acknowledgements")


def drive(config: AgentConfig, options: OrmstcOptions, settings: ConnectionSettings) -> int:
    """Run one ORMSTC robot to its end; the process exit code (agent/main.py)."""
    return run_agent(OrmstcAgent(config, options), settings)
