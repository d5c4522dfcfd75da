"""Client of simhw's hardware API: one robot's body, driven over the bus.

Each command is a query on ``hw/<r>/cmd`` answered when the motion has finished in sim time.
Stepping to a neighbouring sub-cell turns the body the short way round and drives one
sub-cell forward. ``step_to`` retries a bump for a while (a dead body may not have vanished
yet) before it counts as a hardware failure: the takeover's walks. ``try_step_to`` tries
once: the deconflicted walks of ``--recovery rebalance`` decide again after a bump
(agent.offline.runner). A command refused because this robot's incarnation
is stale means the robot was declared dead: FencedError.

Replies can be lost (a router restart drops queries in flight): the retry policy, shared
with the ORMSTC agent, is agent.core.hw_link's (a motion is re-sent only if the pose shows it
was not done).
"""

from __future__ import annotations

import asyncio
import time
from dataclasses import dataclass

from agent.core.errors import HardwareError
from agent.core.hw_link import (
    DEFAULT_TIMEOUT_S,
    HwLink,
    NoReplyError,
    facing,
    standing_on,
    turns,
)
from bus.bridge import Bus
from bus.messages import HwAction, HwReply, Pose
from planner.geometry import Heading, SubCell

__all__ = ["BodyState", "Hardware", "NoReplyError"]

BUMP_RETRY_S = 0.05
BUMP_PATIENCE_S = 5.0


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
                 timeout: float = DEFAULT_TIMEOUT_S) -> None:
        self.robot = robot
        self.incarnation = incarnation
        self.state = BodyState()
        self.link = HwLink(bus, robot, incarnation, timeout=timeout, on_reply=self._seen)

    def _seen(self, reply: HwReply) -> None:
        self.state.pose = reply.pose
        self.state.sim_time = reply.sim_time
        self.state.lost_replies = self.link.lost_replies

    async def command(self, action: HwAction, *, timeout: float | None = None) -> HwReply:
        """Send one command and return its reply; NoReplyError if none comes in time."""
        return await self.link.once(action, timeout=timeout)

    async def wait_for_pose(self, patience: float) -> Pose:
        """The body's pose, polling until simhw answers or ``patience`` seconds pass."""
        return await self.link.wait_for_pose(patience)

    def _check(self, reply: HwReply, action: str) -> None:
        if reply.status != "ok":
            raise HardwareError(f"robot {self.robot}: '{action}' answered {reply.status}: "
                                f"{reply.message}")

    async def step_to(self, target: SubCell) -> None:
        """Turn towards the 4-adjacent sub-cell ``target`` and drive into it, retrying a
        bump for a while (the takeover's walks: nothing else moves the body in the way)."""
        await self._turn_to(target)
        await self._forward(target)

    async def try_step_to(self, target: SubCell) -> bool:
        """Turn towards the 4-adjacent sub-cell ``target`` and drive into it once: False
        when a body (or anything) was in the way (the deconflicted walks decide again)."""
        await self._turn_to(target)
        reply = await self.link.motion("forward", standing_on(target))
        if reply.status == "bumped":
            self.state.bumps += 1
            return False
        self._arrived(reply, target)
        return True

    def _arrived(self, reply: HwReply, target: SubCell) -> None:
        if reply.status != "ok":
            raise HardwareError(f"robot {self.robot}: forward into {target} answered "
                                f"{reply.status}: {reply.message}")
        if (reply.pose[0], reply.pose[1]) != tuple(target):
            raise HardwareError(f"robot {self.robot}: drove to {reply.pose[:2]}, "
                                f"expected {target}")

    async def _turn_to(self, target: SubCell) -> None:
        pose = self.state.pose
        if pose is None:
            raise HardwareError(f"robot {self.robot}: pose unknown; read it first")
        try:
            heading = Heading.from_delta((target[0] - pose[0], target[1] - pose[1]))
        except KeyError:
            raise HardwareError(f"robot {self.robot}: {target} is not next to "
                                f"{pose[:2]}") from None
        for action in turns(pose[2], heading):
            want = (self._heading() + (1 if action == "turn_right" else -1)) % 4
            self._check(await self.link.motion(action, facing(want)), action)

    def _heading(self) -> int:
        assert self.state.pose is not None
        return self.state.pose[2]

    async def _forward(self, target: SubCell) -> None:
        deadline = time.monotonic() + BUMP_PATIENCE_S
        while True:
            reply = await self.link.motion("forward", standing_on(target))
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
