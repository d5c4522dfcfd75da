"""The hardware service: runs HwCommands and AdminCommands against the World in sim time.

Transport-free (bytes in, messages out, ground truth through an injected ``publish``), so the
command semantics are tested without Zenoh; simhw.server binds it to the bus. Commands for one
robot run one at a time (a lock per body), different robots concurrently. A reply is built
when the motion has finished in sim time. Bad payloads and refused commands are answered with
status "rejected" and counted, never raised.
"""

from __future__ import annotations

import asyncio
import logging
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from bus import keys
from bus.codec import decode
from bus.drops import DropCounter
from bus.errors import DecodeError
from bus.messages import (
    NO_ROBOT,
    AdminCommand,
    AdminReply,
    BumpEvent,
    CoverEvent,
    GroundTruthPose,
    HwCommand,
    HwReply,
    HwStatus,
    RobotArray,
    RobotTruth,
    WorldState,
    make_world_state,
)
from simhw.clock import SimClock
from simhw.errors import BodyBusyError, BodyFailedError, BodyFrozenError, CommandRejected
from simhw.kinematics import Kinematics
from simhw.types import BodyStatus, CoverRecord, Odometry, Side, SonarReading, StepResult
from simhw.world import World

Publish = Callable[[str, object], None]
NO_POSE = (-1, -1, 0)
_log = logging.getLogger(__name__)


class FirstVisitors:
    """Who entered each sub-cell first and who first crossed each border between 2 x 2
    cells, folded from the world's cover log (so a late monitor colours cells and tree
    edges as one that watched every CoverEvent)."""

    def __init__(self, shape: tuple[int, int]) -> None:
        h, w = shape[0] // 2, shape[1] // 2
        self.first: RobotArray = np.full(shape, NO_ROBOT, np.uint8)
        self.right: RobotArray = np.full((h, max(w - 1, 0)), NO_ROBOT, np.uint8)
        self.down: RobotArray = np.full((max(h - 1, 0), w), NO_ROBOT, np.uint8)
        self.folded = 0
        self._last: dict[int, tuple[int, int]] = {}

    def fold(self, log: list[CoverRecord]) -> None:
        for rec in log[self.folded:]:
            if rec.robot >= NO_ROBOT:
                raise ValueError(f"robot id {rec.robot} does not fit the packed world state")
            if rec.visits == 1:
                self.first[rec.sub] = rec.robot
            last = self._last.get(rec.robot)
            self._last[rec.robot] = rec.sub
            if last is not None:
                self._cross(rec.robot, last, rec.sub)
        self.folded = len(log)

    def _cross(self, robot: int, a: tuple[int, int], b: tuple[int, int]) -> None:
        (ra, ca), (rb, cb) = (a[0] // 2, a[1] // 2), (b[0] // 2, b[1] // 2)
        if (ra, ca) == (rb, cb) or abs(ra - rb) + abs(ca - cb) != 1:
            return
        border = self.right if ra == rb else self.down
        at = (min(ra, rb), min(ca, cb))
        if border[at] == NO_ROBOT:
            border[at] = robot


@dataclass(frozen=True)
class _Done:
    status: HwStatus
    step: StepResult | None = None
    sonar: SonarReading | None = None
    message: str = ""


class HwService:
    """One world, k bodies, their command queues and the ground-truth publications."""

    def __init__(self, world: World, clock: SimClock, kinematics: Kinematics, mission: str,
                 publish: Publish, time_scale: float = 0.0,
                 frozen_hold_s: float = 600.0) -> None:
        self.world = world
        self.clock = clock
        self.kinematics = kinematics
        self.mission = mission
        self.time_scale = time_scale
        self.frozen_hold_s = frozen_hold_s
        self._publish = publish
        self._locks = [asyncio.Lock() for _ in range(world.k)]
        self._changed = asyncio.Event()
        self._incarnation: dict[int, int] = {}
        self._commanded: dict[int, int] = {}  # robot -> the life its last command came from
        self._covers_sent = 0
        self.firsts = FirstVisitors(world.grid.free.shape)
        self._bumps_sent = 0
        self._fired_seen = 0
        self._pauses_seen = 0
        self.counts: Counter[str] = Counter()
        self.shutdown = asyncio.Event()
        # The bus's drop counter, when served over Zenoh: the bridge drops undecodable
        # requests before they reach us, and "status" must still report them.
        self.drops: DropCounter | None = None

    # ---- hardware commands ---------------------------------------------------------------

    async def command(self, key_robot: int, payload: bytes) -> HwReply:
        """Decode and run one command addressed to ``key_robot``; always returns a reply."""
        try:
            cmd = decode(payload, HwCommand)
        except DecodeError as error:
            self.counts["commands"] += 1
            return self._rejected(-1, key_robot, f"bad command payload: {error}")
        return await self.execute(key_robot, cmd)

    async def execute(self, key_robot: int, cmd: HwCommand) -> HwReply:
        """Run a decoded command addressed (by its key) to ``key_robot``."""
        self.counts["commands"] += 1
        if cmd.robot != key_robot:
            return self._rejected(cmd.cmd_id, key_robot,
                                  f"command for robot {cmd.robot} sent to robot {key_robot}")
        if not 0 <= cmd.robot < self.world.k:
            return self._rejected(cmd.cmd_id, cmd.robot, f"no robot {cmd.robot}")
        stale = self._fence(cmd)
        if stale:
            return self._rejected(cmd.cmd_id, cmd.robot, stale)
        async with self._locks[cmd.robot]:
            done = await self._run_held(cmd)
        self.counts[done.status] += 1
        self._flush_ground_truth()
        return self._reply(cmd.cmd_id, cmd.robot, done)

    def reject_empty(self, robot: int) -> HwReply:
        """The reply to a command query that carried no payload at all."""
        self.counts["commands"] += 1
        return self._rejected(-1, robot, "command query without a payload")

    def _fence(self, cmd: HwCommand) -> str:
        """A command from an older incarnation than one already seen is refused."""
        newest = self._incarnation.get(cmd.robot, cmd.incarnation)
        if cmd.incarnation < newest:
            return f"incarnation {cmd.incarnation} of robot {cmd.robot} is stale ({newest})"
        self._incarnation[cmd.robot] = cmd.incarnation
        self._commanded[cmd.robot] = cmd.incarnation
        return ""

    def life_is_fenced(self, robot: int) -> bool:
        """True while ``robot``'s newest life seen here is fenced (no newer life since)."""
        return self._incarnation.get(robot, 0) > self._commanded.get(robot, 0)

    def fence_life(self, robot: int, incarnation: int) -> None:
        """Refuse from now on every command of ``robot``'s lives up to ``incarnation``."""
        newest = self._incarnation.get(robot, incarnation + 1)
        self._incarnation[robot] = max(newest, incarnation + 1)

    async def _run_held(self, cmd: HwCommand) -> _Done:
        """Run the command, holding it while the body is frozen (a hung robot)."""
        try:
            while True:
                # Only the wait before a motion is bounded: a motion already under way holds
                # a reservation, so it must finish (or fail) rather than be abandoned.
                async with asyncio.timeout(self.frozen_hold_s):
                    await self._until_not_frozen(cmd.robot)
                try:
                    return await self._run(cmd)
                except BodyFrozenError:
                    continue
        except TimeoutError:
            return _Done("frozen", message=f"robot {cmd.robot} stayed frozen for "
                                           f"{self.frozen_hold_s:g} s")
        except BodyFailedError as error:
            return _Done("failed", message=str(error))
        except (CommandRejected, BodyBusyError) as error:
            return _Done("rejected", message=str(error))

    async def _until_not_frozen(self, robot: int) -> None:
        # and not held by a pause of the whole world (World.pause_at)
        while self.world.body(robot).status is BodyStatus.FROZEN or self.world.paused:
            await self._changed.wait()

    def _notify(self) -> None:
        # Wake every waiter once; each re-checks its own body and waits on the fresh event.
        self._changed.set()
        self._changed = asyncio.Event()

    async def _run(self, cmd: HwCommand) -> _Done:
        robot, action = cmd.robot, cmd.action
        if action in ("pose", "stop"):
            # Motions are atomic and serialised per body, so "stop" has nothing to interrupt.
            return _Done("ok", StepResult(robot, self.world.body(robot).pose, Odometry()))
        if action == "sense":
            self.world.check_ready(robot)
            await self.clock.run(robot, self.kinematics.sense_s)
            return _Done("ok", sonar=self.world.sense(robot, cmd.sensors),
                         step=StepResult(robot, self.world.body(robot).pose, Odometry()))
        if action in ("turn_left", "turn_right"):
            self.world.check_ready(robot)
            await self.clock.run(robot, self.kinematics.turn_s())
            side = Side.LEFT if action == "turn_left" else Side.RIGHT
            step = self.world.turn(robot, side)
            self._publish_pose(robot)
            return _Done("ok", step)
        if action == "forward":
            return await self._forward(robot)
        raise CommandRejected(f"unknown action {action!r}")

    async def _forward(self, robot: int) -> _Done:
        outcome = self.world.begin_forward(robot, self.clock.lane_now(robot))
        if outcome.bumped:
            # The body drives until the bumper closes, then backs off: half a step each way.
            await self.clock.run(robot, self.kinematics.forward_s())
            return _Done("bumped", self.world.bumped_step(robot),
                         message=f"bumped into {outcome.cause.value if outcome.cause else '?'}"
                                 f" at {outcome.target}")
        await self.clock.run(robot, self.kinematics.forward_s())
        # Frozen mid-motion: the body hangs before arriving; it arrives once unfrozen.
        await self._until_not_frozen(robot)
        step = self.world.finish_move(robot, self.clock.lane_now(robot))
        self._publish_pose(robot)
        return _Done("ok", step)

    # ---- admin ---------------------------------------------------------------------------

    def admin(self, payload: bytes) -> AdminReply:
        """Decode and run an admin command; synchronous so "shutdown" is answered at once."""
        try:
            cmd = decode(payload, AdminCommand)
        except DecodeError as error:
            self.counts["admin"] += 1
            self.counts["rejected"] += 1
            return AdminReply(ok=False, message=f"bad admin payload: {error}")
        return self.admin_command(cmd)

    def admin_command(self, cmd: AdminCommand) -> AdminReply:
        self.counts["admin"] += 1
        try:
            reply = self._admin(cmd)
        except (CommandRejected, BodyFailedError) as error:
            return AdminReply(ok=False, message=str(error))
        self._notify()
        return reply

    def _admin(self, cmd: AdminCommand) -> AdminReply:
        if cmd.action == "status":
            return AdminReply(ok=True, message="status", data=self.status())
        if cmd.action == "shutdown":
            self.shutdown.set()
            return AdminReply(ok=True, message="shutting down")
        if cmd.action in ("pause", "resume"):
            return self._pause_or_resume(cmd)
        if cmd.robot is None:
            raise CommandRejected(f"admin {cmd.action} needs a robot")
        if cmd.after_covered is not None:
            return self._arm_failure(cmd.robot, cmd.action, cmd.after_covered)
        {"fail": self.world.fail, "freeze": self.world.freeze,
         "unfreeze": self.world.unfreeze}[cmd.action](cmd.robot)
        return AdminReply(ok=True, message=f"robot {cmd.robot}: {cmd.action} done",
                          data={"robot": cmd.robot,
                                "status": self.world.body(cmd.robot).status.value})

    def _arm_failure(self, robot: int, action: str, covered: int) -> AdminReply:
        if action != "fail":
            raise CommandRejected(f"admin {action} cannot wait for coverage; only fail can")
        if covered < 0:
            raise CommandRejected(f"after_covered must be 0 or more, got {covered}")
        now = self.world.arm_failure(robot, covered, self.clock.now())
        self._report_fired()
        return AdminReply(ok=True, message=f"robot {robot}: fail " + (
            "done" if now else f"armed for {covered} covered sub-cells"),
            data={"robot": robot, "status": self.world.body(robot).status.value,
                  "covered": self.world.covered})

    def _pause_or_resume(self, cmd: AdminCommand) -> AdminReply:
        if cmd.action == "resume":
            self.world.resume()
            self._notify()
            return AdminReply(ok=True, message="resumed", data={"covered": self.world.covered})
        if cmd.after_covered is None or cmd.after_covered < 0:
            raise CommandRejected("pause needs after_covered, 0 or more")
        now = self.world.pause_at(cmd.after_covered, self.clock.now())
        self._report_fired()
        return AdminReply(ok=True, message="paused" if now else
                          f"pause armed for {cmd.after_covered} covered sub-cells",
                          data={"covered": self.world.covered})

    def _report_fired(self) -> None:
        for covered, at in self.world.pauses[self._pauses_seen:]:
            _log.warning("every body held at %d covered sub-cells (sim %.1f s), until resumed",
                         covered, at)
        self._pauses_seen = len(self.world.pauses)
        for robot, covered, at in self.world.fired[self._fired_seen:]:
            _log.warning("robot %d's body failed as armed, at %d covered sub-cells (sim %.1f s)",
                         robot, covered, at)
        if len(self.world.fired) > self._fired_seen:
            self._fired_seen = len(self.world.fired)
            self._notify()  # a frozen body waiting in _until_not_frozen fails now

    def status(self) -> dict[str, int | float | str]:
        data: dict[str, int | float | str] = {
            "robots": self.world.k, "sim_time": self.clock.now(),
            "covered": self.world.covered,
            "free": int(self.world.grid.free.sum())}
        data.update({f"count.{k}": v for k, v in sorted(self.counts.items())})
        data.update({f"robot.{b.robot}": b.status.value for b in self.world.bodies()})
        if self.drops is not None:
            data.update({f"drops.{kind}.{why}": n
                         for (kind, why), n in sorted(self.drops.snapshot().items())})
        return data

    # ---- ground truth --------------------------------------------------------------------

    def world_state(self) -> WorldState:
        covered = Counter(rec.robot for rec in self.world.cover_log)
        robots = tuple(
            RobotTruth(robot=b.robot, pose=b.pose.as_tuple(),
                       alive=b.status is BodyStatus.ALIVE,
                       frozen=b.status is BodyStatus.FROZEN,
                       failed=b.status is BodyStatus.FAILED, covered=covered[b.robot])
            for b in self.world.bodies())
        self.firsts.fold(self.world.cover_log)
        return make_world_state(self.world.grid.name, self.world.grid.free, self.world.visits,
                                robots, self.clock.now(), self.time_scale,
                                first=self.firsts.first,
                                crossed=(self.firsts.right, self.firsts.down))

    def publish_initial(self) -> None:
        """Poses and start-cell covers of every body, for subscribers already listening."""
        for b in self.world.bodies():
            self._publish_pose(b.robot)
        self._flush_ground_truth()

    def _publish_pose(self, robot: int) -> None:
        pose = self.world.body(robot).pose.as_tuple()
        self._publish(keys.sim_pose(self.mission, robot),
                      GroundTruthPose(robot=robot, pose=pose,
                                      sim_time=self.clock.lane_now(robot)))

    def _flush_ground_truth(self) -> None:
        self._report_fired()
        for rec in self.world.cover_log[self._covers_sent:]:
            self._publish(keys.sim_cover(self.mission, rec.robot),
                          CoverEvent(robot=rec.robot, cell=rec.sub, sim_time=rec.time,
                                     visits=rec.visits))
        self._covers_sent = len(self.world.cover_log)
        for bump in self.world.bump_log[self._bumps_sent:]:
            self._publish(keys.sim_bump(self.mission, bump.robot),
                          BumpEvent(robot=bump.robot, at=bump.at, into=bump.into,
                                    sim_time=bump.time))
        self._bumps_sent = len(self.world.bump_log)

    # ---- replies -------------------------------------------------------------------------

    def _reply(self, cmd_id: int, robot: int, done: _Done) -> HwReply:
        pose = self.world.body(robot).pose
        odometry = done.step.odometry if done.step else Odometry()
        return HwReply(
            cmd_id=cmd_id, robot=robot, status=done.status,
            message=done.message, pose=pose.as_tuple(),
            odometry=(odometry.forward_m, odometry.turn_rad),
            sonar=dict(done.sonar.ranges) if done.sonar else {},
            bumper=self.world.bumper(robot), sim_time=self.clock.lane_now(robot))

    def _rejected(self, cmd_id: int, robot: int, message: str) -> HwReply:
        self.counts["rejected"] += 1
        known = 0 <= robot < self.world.k
        return HwReply(
            cmd_id=cmd_id, robot=robot, status="rejected", message=message,
            pose=self.world.body(robot).pose.as_tuple() if known else NO_POSE,
            odometry=(0.0, 0.0), sonar={}, bumper=False, sim_time=self.clock.now())
