"""One body's command channel to simhw, and the one retry policy every agent uses on it.

A command is a query on ``hw/<r>/cmd``, answered when the motion is over in sim time. A
query can come back empty: at once while the router is away (a restart), or after the
attempt timeout. Until the link's deadline (``timeout``, 60 s by default) the policy is:

- a command that changes nothing (``pose``, ``sense``) is simply sent again;
- a motion is never blindly re-sent, since a lost *reply* does not mean a lost *motion*:
  the link asks for the pose (simhw runs one command per body at a time, so that answer
  comes after the motion has finished) and re-sends the motion only if the pose shows it
  was not done.

A command refused because this robot's incarnation is stale means the robot was declared
dead: FencedError, never retried. Error messages say how long the link actually waited.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable

from agent.core.config import DEFAULT_HW_TIMEOUT
from agent.core.errors import FencedError, HardwareError
from bus import keys
from bus.bridge import Bus
from bus.messages import HwAction, HwCommand, HwReply, Pose, Sensor

POLL_S = 0.2  # pause between attempts while simhw (or the router) does not answer
ATTEMPT_S = 5.0  # longest wait for one reply (a motion lasts ~2 sim seconds)
DEFAULT_TIMEOUT_S = DEFAULT_HW_TIMEOUT
# Quarter turns right (mod 4) -> the turns that make them the short way round; headings as
# in planner.geometry (clockwise, a right turn is +1).
_TURNS: dict[int, tuple[HwAction, ...]] = {
    0: (), 1: ("turn_right",), 2: ("turn_right", "turn_right"), 3: ("turn_left",)}


class NoReplyError(HardwareError):
    """No reply to one command within its timeout (it may or may not have run)."""


class HwLink:
    """Numbered commands for one body, at most one in flight (callers await each).

    ``on_reply`` sees every reply that carries a pose (``ok`` or ``bumped``).
    """

    def __init__(self, bus: Bus, robot: int, incarnation: int, *,
                 timeout: float = DEFAULT_TIMEOUT_S,
                 on_reply: Callable[[HwReply], None] = lambda _reply: None) -> None:
        self._bus = bus
        self._key = keys.hw_cmd(bus.mission, robot)
        self.robot = robot
        self.incarnation = incarnation
        self.timeout = timeout
        self.lost_replies = 0
        self._on_reply = on_reply
        self._next_id = 1

    async def once(self, action: HwAction, sensors: tuple[Sensor, ...] = (), *,
                   timeout: float | None = None) -> HwReply:
        """Send one command and return its reply; NoReplyError if none comes in time."""
        cmd = HwCommand(self._next_id, self.robot, self.incarnation, action, sensors)
        self._next_id += 1
        wait = min(self.timeout, ATTEMPT_S) if timeout is None else timeout
        began = time.monotonic()
        replies = await self._bus.query(self._key, cmd, HwReply, timeout=wait)
        reply = next((rx.msg for rx in replies if rx.msg.cmd_id == cmd.cmd_id), None)
        if reply is None:
            raise NoReplyError(f"robot {self.robot}: no reply from simhw to '{action}' "
                               f"after {time.monotonic() - began:.1f} s (is simhw running, "
                               "and the router reachable?)")
        if reply.status == "rejected" and "stale" in reply.message:
            raise FencedError(f"robot {self.robot}: simhw refuses incarnation "
                              f"{self.incarnation}: {reply.message}")
        if reply.status in ("ok", "bumped"):
            self._on_reply(reply)
        return reply

    async def ask(self, action: HwAction, sensors: tuple[Sensor, ...] = ()) -> HwReply:
        """A command that changes nothing: sent again until answered or the deadline."""
        deadline = time.monotonic() + self.timeout
        attempts = 0
        while True:
            attempts += 1
            try:
                return await self.once(action, sensors,
                                       timeout=self._attempt(deadline))
            except NoReplyError:
                self.lost_replies += 1
                self._give_up_after(deadline, action, attempts)
                await asyncio.sleep(POLL_S)

    async def motion(self, action: HwAction, done: Callable[[Pose], bool]) -> HwReply:
        """Run a motion once, surviving lost replies (see the module docstring).

        Returns the motion's reply, or the pose reply that showed it done.
        """
        deadline = time.monotonic() + self.timeout
        attempts = 0
        while True:
            attempts += 1
            try:
                return await self.once(action, timeout=self._attempt(deadline))
            except NoReplyError:
                self.lost_replies += 1
            while True:
                self._give_up_after(deadline, action, attempts)
                try:
                    reply = await self.once("pose", timeout=self._attempt(deadline))
                except NoReplyError:
                    await asyncio.sleep(POLL_S)
                    continue
                if reply.status != "ok":
                    return reply  # failed or frozen: the caller reports it
                if done(reply.pose):
                    return reply
                break  # the motion did not happen: send it again

    async def wait_for_pose(self, patience: float) -> Pose:
        """The body's pose, polling until simhw answers or ``patience`` seconds pass."""
        deadline = time.monotonic() + patience
        while True:
            try:
                reply = await self.once("pose", timeout=max(min(1.0, self._left(deadline)),
                                                            0.1))
            except NoReplyError:
                if time.monotonic() >= deadline:
                    raise HardwareError(
                        f"robot {self.robot}: simhw did not answer within {patience:g} s "
                        "(is it running on this mission, with this many robots?)") from None
                await asyncio.sleep(POLL_S)
                continue
            if reply.status != "ok":
                raise HardwareError(f"robot {self.robot}: 'pose' answered {reply.status}: "
                                    f"{reply.message}")
            return reply.pose

    @staticmethod
    def _left(deadline: float) -> float:
        return deadline - time.monotonic()

    def _attempt(self, deadline: float) -> float:
        return max(min(ATTEMPT_S, self._left(deadline)), 0.1)

    def _give_up_after(self, deadline: float, action: str, attempts: int) -> None:
        if time.monotonic() >= deadline:
            raise HardwareError(f"robot {self.robot}: no answer from simhw to '{action}' "
                                f"within {self.timeout:g} s ({attempts} attempts)")


def turns(heading: int, towards: int) -> tuple[HwAction, ...]:
    """The turns from ``heading`` to ``towards``, the short way round."""
    return _TURNS[(towards - heading) % 4]


def facing(heading: int) -> Callable[[Pose], bool]:
    """``done`` for a turn: the body faces ``heading``."""
    return lambda pose: pose[2] == heading


def standing_on(target: tuple[int, int]) -> Callable[[Pose], bool]:
    """``done`` for a forward step: the body stands on ``target``."""
    return lambda pose: (pose[0], pose[1]) == tuple(target)
