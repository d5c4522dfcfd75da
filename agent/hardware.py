"""Client of simhw's hardware API: one robot's body, driven over the bus.

Each command is a query on ``hw/<r>/cmd`` answered when the motion has finished in sim time.
Stepping to a neighbouring sub-cell turns the body the short way round and drives one
sub-cell forward. A bump is retried for a while (a dead body may not have vanished yet)
before it counts as a hardware failure. A command refused because this robot's incarnation
is stale means the robot was declared dead: FencedError.

Replies can be lost (a router restart drops queries in flight), and re-sending a motion
whose reply was lost could move the body twice. So a motion without a reply is followed by
"pose" commands — simhw runs one command per body at a time, so the pose answer comes after
the lost motion has finished — and the motion is re-sent only if the pose shows it was not
done.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable
from dataclasses import dataclass

from agent.errors import FencedError, HardwareError
from bus import keys
from bus.bridge import Bus
from bus.messages import HwAction, HwCommand, HwReply, Pose
from planner.types import SubCell

# Heading of each unit step (d_row, d_col): 0 = N, 1 = E, 2 = S, 3 = W (bus.messages).
_HEADING_OF = {(-1, 0): 0, (0, 1): 1, (1, 0): 2, (0, -1): 3}
_TURNS: dict[int, tuple[HwAction, ...]] = {
    0: (), 1: ("turn_right",), 2: ("turn_right", "turn_right"), 3: ("turn_left",)}
BUMP_RETRY_S = 0.05
BUMP_PATIENCE_S = 5.0
POLL_S = 0.2
# How long to wait for one reply before asking for the pose (a motion lasts ~2 sim seconds).
ATTEMPT_S = 5.0


def _facing(heading: int) -> Callable[[Pose], bool]:
    return lambda pose: pose[2] == heading


class NoReplyError(HardwareError):
    """No reply to one command within its timeout (it may or may not have run)."""


@dataclass
class BodyState:
    """The last pose and sim time the hardware reported."""

    pose: Pose | None = None
    sim_time: float = 0.0
    bumps: int = 0
    lost_replies: int = 0


class Hardware:
    """Commands for one body; at most one in flight (the caller awaits each). ``timeout``
    bounds how long one motion may take, lost replies and re-tries included."""

    def __init__(self, bus: Bus, robot: int, incarnation: int, *,
                 timeout: float = 60.0) -> None:
        self._bus = bus
        self._key = keys.hw_cmd(bus.mission, robot)
        self.robot = robot
        self.incarnation = incarnation
        self.timeout = timeout
        self.state = BodyState()
        self._next_id = 1

    async def command(self, action: HwAction, *, timeout: float | None = None) -> HwReply:
        """Send one command and return its reply; NoReplyError if none comes in time."""
        cmd_id = self._next_id
        self._next_id += 1
        cmd = HwCommand(cmd_id=cmd_id, robot=self.robot, incarnation=self.incarnation,
                        action=action)
        wait = min(self.timeout, ATTEMPT_S) if timeout is None else timeout
        replies = await self._bus.query(self._key, cmd, HwReply, timeout=wait)
        mine = [rx.msg for rx in replies if rx.msg.cmd_id == cmd_id]
        if not mine:
            raise NoReplyError(f"robot {self.robot}: no reply from the hardware to "
                               f"'{action}' within {wait:g} s (is simhw running?)")
        reply = mine[0]
        if reply.status == "rejected" and "stale" in reply.message:
            raise FencedError(f"robot {self.robot}: hardware refuses incarnation "
                              f"{self.incarnation}: {reply.message}")
        if reply.status in ("ok", "bumped"):
            self.state.pose = reply.pose
            self.state.sim_time = reply.sim_time
        return reply

    async def wait_for_pose(self, patience: float) -> Pose:
        """The body's pose, polling until simhw answers or ``patience`` seconds pass."""
        deadline = time.monotonic() + patience
        while True:
            left = deadline - time.monotonic()
            try:
                reply = await self.command("pose", timeout=max(min(1.0, left), 0.1))
            except NoReplyError:
                if time.monotonic() >= deadline:
                    raise HardwareError(
                        f"robot {self.robot}: simhw did not answer within {patience:g} s "
                        "(is it running on this mission, with this many robots?)") from None
                await asyncio.sleep(POLL_S)
                continue
            self._check(reply, "pose")
            return reply.pose

    def _check(self, reply: HwReply, action: str) -> None:
        if reply.status != "ok":
            raise HardwareError(f"robot {self.robot}: '{action}' answered {reply.status}: "
                                f"{reply.message}")

    async def _motion(self, action: HwAction, done: Callable[[Pose], bool]) -> HwReply:
        """Run a motion once, surviving lost replies (see the module docstring)."""
        deadline = time.monotonic() + self.timeout
        while True:
            try:
                return await self.command(action)
            except NoReplyError:
                self.state.lost_replies += 1
            while True:
                if time.monotonic() >= deadline:
                    raise HardwareError(f"robot {self.robot}: no answer to '{action}' "
                                        f"within {self.timeout:g} s")
                try:
                    reply = await self.command("pose")
                except NoReplyError:
                    await asyncio.sleep(POLL_S)
                    continue
                self._check(reply, "pose")
                if done(reply.pose):
                    return reply
                break  # the motion did not happen: send it again

    async def step_to(self, target: SubCell) -> None:
        """Turn towards the 4-adjacent sub-cell ``target`` and drive into it."""
        pose = self.state.pose
        if pose is None:
            raise HardwareError(f"robot {self.robot}: pose unknown; read it first")
        heading = _HEADING_OF.get((target[0] - pose[0], target[1] - pose[1]))
        if heading is None:
            raise HardwareError(f"robot {self.robot}: {target} is not next to {pose[:2]}")
        for action in _TURNS[(heading - pose[2]) % 4]:
            want = (self._heading() + (1 if action == "turn_right" else -1)) % 4
            self._check(await self._motion(action, _facing(want)), action)
        await self._forward(target)

    def _heading(self) -> int:
        assert self.state.pose is not None
        return self.state.pose[2]

    async def _forward(self, target: SubCell) -> None:
        deadline = time.monotonic() + BUMP_PATIENCE_S
        while True:
            reply = await self._motion("forward", lambda p: (p[0], p[1]) == tuple(target))
            if reply.status == "ok":
                if (reply.pose[0], reply.pose[1]) != tuple(target):
                    raise HardwareError(f"robot {self.robot}: drove to {reply.pose[:2]}, "
                                        f"expected {target}")
                return
            if reply.status != "bumped" or time.monotonic() >= deadline:
                raise HardwareError(f"robot {self.robot}: forward into {target} answered "
                                    f"{reply.status}: {reply.message}")
            self.state.bumps += 1
            await asyncio.sleep(BUMP_RETRY_S)
