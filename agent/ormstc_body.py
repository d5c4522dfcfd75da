"""simhw's hardware API as the ORMSTC driver uses it: one body, one command at a time.

Each command is a query on ``hw/<r>/cmd`` answered when the motion is over in sim time. Unlike
agent.hardware (the offline agent's client) a bump is returned, not retried: the ORMSTC
machine backs off and retries itself. Sense commands name their sonars; when simhw runs in
one-at-a-time mode (it rejects several), every later sense names one.
"""

from __future__ import annotations

import asyncio
import time

from agent.errors import FencedError, HardwareError
from bus import keys
from bus.bridge import Bus
from bus.messages import HwAction, HwCommand, HwReply, Sensor

_TURNS: dict[int, tuple[HwAction, ...]] = {
    0: (), 1: ("turn_right",), 2: ("turn_right", "turn_right"), 3: ("turn_left",)}


class Body:
    """simhw's hardware API for one robot: commands are queries answered after the motion."""

    def __init__(self, bus: Bus, robot: int, incarnation: int, timeout: float) -> None:
        self._bus = bus
        self._key = keys.hw_cmd(bus.mission, robot)
        self.robot, self.incarnation, self.timeout = robot, incarnation, timeout
        self.pose: tuple[int, int, int] | None = None
        self.one_sonar = False  # set once simhw says one sonar per command
        self._next = 0

    async def command(self, action: HwAction, sensors: tuple[Sensor, ...] = (),
                      timeout: float | None = None) -> HwReply:
        self._next += 1
        cmd = HwCommand(self._next, self.robot, self.incarnation, action, sensors)
        wait = self.timeout if timeout is None else timeout
        replies = await self._bus.query(self._key, cmd, HwReply, timeout=wait)
        reply = next((rx.msg for rx in replies if rx.msg.cmd_id == cmd.cmd_id), None)
        if reply is None:
            raise HardwareError(f"robot {self.robot}: no reply from simhw to '{action}' "
                                f"within {wait:g} s")
        if reply.status == "rejected" and "stale" in reply.message:
            raise FencedError(f"robot {self.robot}: simhw refuses incarnation "
                              f"{self.incarnation}: {reply.message}")
        if reply.status in ("ok", "bumped"):
            self.pose = reply.pose
        return reply

    async def must(self, action: HwAction, sensors: tuple[Sensor, ...] = ()) -> HwReply:
        reply = await self.command(action, sensors)
        if reply.status != "ok":
            raise HardwareError(f"robot {self.robot}: '{action}' answered {reply.status}: "
                                f"{reply.message}")
        return reply

    async def wait_for_pose(self, patience: float) -> tuple[int, int, int]:
        deadline = time.monotonic() + patience
        while True:
            try:
                return (await self.must("pose", ())).pose
            except HardwareError:
                if time.monotonic() >= deadline:
                    raise HardwareError(f"robot {self.robot}: simhw did not answer within "
                                        f"{patience:g} s (is simhw running?)") from None
                await asyncio.sleep(0.2)

    async def face(self, heading: int) -> None:
        assert self.pose is not None
        action: HwAction
        for action in _TURNS[(heading - self.pose[2]) % 4]:
            await self.must(action)

    async def sonar(self, sensors: tuple[Sensor, ...]) -> dict[str, int | None]:
        """Ranges of ``sensors``: one command, or one each in one-at-a-time mode."""
        if len(sensors) > 1 and not self.one_sonar:
            reply = await self.command("sense", sensors)
            if reply.status == "ok":
                return dict(reply.sonar)
            if reply.status != "rejected":
                raise HardwareError(f"robot {self.robot}: sense answered {reply.status}")
            self.one_sonar = True  # simhw runs --sonar-mode one-at-a-time
        ranges: dict[str, int | None] = {}
        for sensor in sensors:
            ranges.update((await self.must("sense", (sensor,))).sonar)
        return ranges
