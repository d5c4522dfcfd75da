"""Sensing steps made visible, and sensing that spares them.

:class:`MarkedSteps` is the body as agent.ormstc.body.look sees it: a look moves the robot
only to step to the sub-cell beside it and back (a thin sonar sees one half of a
neighbouring cell), so every forward step made through it is a sensing step; the driver
publishes each one (bus.messages.LookStep), and a report can tell these entries from
coverage revisits (docs/monitor.md, "Redundancy").

:func:`glance` reads, after a move, the sonars whose rays may cross a sub-cell never seen,
and remembers what they show: a reading costs 0.1 s of simhw time and no motion, a look
from beside two steps and about two turns, and the memory spares many of those
(docs/ormstc.md, "Sensing with a thin sonar").
"""

from __future__ import annotations

from collections.abc import Callable

from agent.ormstc.body import Hardware
from agent.ormstc.sensing import BodyTest, SonarMap, direction_of, shows_news
from bus.messages import Sensor
from planner.ormstc.types import SubCell

_SONARS: tuple[Sensor, ...] = ("front", "left", "right")

StepSink = Callable[[int, SubCell], None]  # (the step's number from 1, the sub-cell entered)


class MarkedSteps:
    """A body's face / forward / sonar for :func:`agent.ormstc.body.look`; each forward
    step that moved the body is numbered and handed to ``on_step``."""

    def __init__(self, body: Hardware, on_step: StepSink) -> None:
        self._body = body
        self._on_step = on_step
        self.steps = 0

    @property
    def pose(self) -> tuple[int, int, int] | None:
        return self._body.pose

    @pose.setter
    def pose(self, value: tuple[int, int, int] | None) -> None:
        self._body.pose = value

    async def face(self, heading: int) -> None:
        await self._body.face(heading)

    async def forward(self) -> bool:
        moved = await self._body.forward()
        pose = self._body.pose
        if moved and pose is not None:
            self.steps += 1
            self._on_step(self.steps, (pose[0], pose[1]))
        return moved

    async def sonar(self, sensors: tuple[Sensor, ...]) -> dict[str, int | None]:
        return await self._body.sonar(sensors)


async def glance(body: Hardware, sonar: SonarMap, may_hold_body: BodyTest) -> int:
    """Read the sonars that may show something new from where the body stands, remember
    the rays (as :func:`agent.ormstc.body.look` does) and return how many were read."""
    if body.pose is None:
        return 0
    pos, heading = (body.pose[0], body.pose[1]), body.pose[2]
    sensors = tuple(s for s in _SONARS if shows_news(sonar, pos, direction_of(heading, s)))
    if not sensors:
        return 0
    ranges = await body.sonar(sensors)
    for sensor in sensors:
        sonar.record(pos, direction_of(heading, sensor), ranges.get(sensor), may_hold_body)
    sonar.readings += len(sensors)
    sonar.glance_readings += len(sensors)
    return len(sensors)
