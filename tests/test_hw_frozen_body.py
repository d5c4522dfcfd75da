"""The agent's side of ``--hw-timeout`` against a scripted simhw (no processes): a frozen body
makes the step fail with the link's deadline; a body unfrozen before it is not driven twice;
a bumped forward step is retried until it goes through."""

from __future__ import annotations

import asyncio
from typing import Any, cast

import pytest

from agent.core.errors import HardwareError
from agent.offline.hardware import Hardware
from bus.inbox import Received
from bus.messages import HwCommand, HwReply, HwStatus, Pose

EAST = 1  # planner.geometry.Heading.E: from (0, 0) the step to (0, 1) needs no turn


class ScriptedSimhw:
    """Answers hw commands like simhw: ``frozen_for`` commands are held past their timeout
    (a frozen body), ``bumps`` forward steps are refused with "bumped"; a forward that ran
    moves the body one sub-cell east."""

    def __init__(self, *, frozen_for: int = 0, bumps: int = 0, runs_while_frozen: bool = False
                 ) -> None:
        self.mission = "t"
        self.pose: Pose = (0, 0, EAST)
        self.frozen_for = frozen_for
        self.bumps = bumps
        self.runs_while_frozen = runs_while_frozen
        self.sent: list[str] = []

    def reply(self, cmd: HwCommand, status: HwStatus) -> list[Received[HwReply]]:
        return [Received("hw", HwReply(cmd.cmd_id, cmd.robot, status, "", self.pose, (0.0, 0.0),
                                       {}, status == "bumped", 0.0))]

    async def query(self, key: str, cmd: HwCommand, _type: Any, *,
                    timeout: float) -> list[Received[HwReply]]:
        self.sent.append(cmd.action)
        if self.frozen_for > 0:
            self.frozen_for -= 1
            if cmd.action == "forward" and self.runs_while_frozen:
                self.pose = (self.pose[0], self.pose[1] + 1, self.pose[2])  # done, reply lost
            await asyncio.sleep(min(timeout, 0.05))  # the query's wait, shortened
            return []
        if cmd.action == "forward":
            if self.bumps > 0:
                self.bumps -= 1
                return self.reply(cmd, "bumped")
            self.pose = (self.pose[0], self.pose[1] + 1, self.pose[2])
        return self.reply(cmd, "ok")


def body_on(simhw: ScriptedSimhw, timeout: float) -> Hardware:
    hardware = Hardware(cast(Any, simhw), 0, 1, timeout=timeout)
    hardware.state.pose = simhw.pose
    return hardware


async def test_a_frozen_body_fails_the_step_at_the_hw_timeout() -> None:
    simhw = ScriptedSimhw(frozen_for=10**6)
    with pytest.raises(HardwareError, match=r"within 0.5 s"):
        await body_on(simhw, 0.5).step_to((0, 1))
    # the positive witness: the link kept asking for the pose until its deadline
    assert simhw.sent[0] == "forward" and simhw.sent.count("pose") >= 2
    assert simhw.sent.count("forward") == 1, "a motion is never blindly re-sent"


async def test_a_body_unfrozen_in_time_is_not_driven_twice() -> None:
    simhw = ScriptedSimhw(frozen_for=1, runs_while_frozen=True)
    hardware = body_on(simhw, 30.0)
    await hardware.step_to((0, 1))
    assert simhw.pose[:2] == (0, 1) and hardware.state.pose == simhw.pose
    assert simhw.sent == ["forward", "pose"]


async def test_a_motion_lost_while_frozen_is_sent_again() -> None:
    simhw = ScriptedSimhw(frozen_for=1)
    await body_on(simhw, 30.0).step_to((0, 1))
    assert simhw.sent == ["forward", "pose", "forward"] and simhw.pose[:2] == (0, 1)


async def test_a_bumped_step_is_retried_until_it_goes_through() -> None:
    simhw = ScriptedSimhw(bumps=2)
    hardware = body_on(simhw, 30.0)
    await hardware.step_to((0, 1))
    assert hardware.state.bumps == 2
    assert simhw.sent == ["forward"] * 3 and simhw.pose[:2] == (0, 1)
