"""Sensing steps made visible, and sensing that spares them.

:class:`MarkedSteps` is the body as agent.ormstc.body.look sees it: a look moves the robot
only to step to the sub-cell beside it and back (a thin sonar sees one half of a
neighbouring cell), so a forward step made through it is a sensing step unless the walk
goes on from there; the driver publishes each sensing step (bus.messages.LookStep), and a
report can tell these entries from coverage revisits (docs/monitor.md, "Redundancy").

:class:`Looker` does not step back after a look: the sub-cell beside is the corner the STC
walk turns to next whenever the robot does not grow into the looked-at cell (an obstacle, a
body, a lost claim), so it steps back only when the machine's next move leaves from the
sub-cell it believes in, and otherwise the step aside was that move.

The Looker also carries out looks from inside (planner/ormstc/inside.py): a Sense of the
cell the body stands in. Its step on to the next sub-cell is held like a step aside; when
the cell is given up, the step into it and the step back out (the machine's moves) are
published as look steps too (:meth:`Looker.walked`).

:func:`glance` reads, after a move, the sonars whose rays may cross a sub-cell never seen,
and remembers what they show: a reading costs 0.1 s of simhw time and no motion, a look
from beside two steps and about two turns, and the memory spares many of those
(docs/ormstc.md, "Sensing with a thin sonar").
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

from agent.core.errors import HardwareError
from agent.ormstc.body import Hardware, look, step_back
from agent.ormstc.sensing import BodyTest, SonarMap, cell_of, direction_of, shows_news
from bus.messages import Sensor
from planner.ormstc.types import CellStatus, Sense, SenseMode, SenseResult, SubCell

_SONARS: tuple[Sensor, ...] = ("front", "left", "right")

StepSink = Callable[[int, SubCell], None]  # (the step's number from 1, the sub-cell entered)


class MarkedSteps:
    """A body's face / forward / sonar for :func:`agent.ormstc.body.look`; each forward
    step that moved the body is held until :meth:`publish` numbers it and hands it to
    ``on_step`` (or :meth:`publish` is told the last one was a coverage move)."""

    def __init__(self, body: Hardware, on_step: StepSink) -> None:
        self._body = body
        self._on_step = on_step
        self.steps = 0  # the look steps published
        self.held: list[SubCell] = []  # sub-cells entered, not published yet

    def mark(self, sub: SubCell) -> None:
        """Publish a step the walk made as a look step after all (a cell given up from
        inside: the step into it and the step back, planner/ormstc/inside.py)."""
        self.steps += 1
        self._on_step(self.steps, sub)

    def publish(self, last_walked: bool = False) -> None:
        """Publish the held steps as look steps; with ``last_walked`` the last one was the
        walk's own move into its sub-cell and is not one."""
        for sub in self.held[:-1] if last_walked else self.held:
            self.steps += 1
            self._on_step(self.steps, sub)
        self.held = []

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
            self.held.append((pose[0], pose[1]))
        return moved

    async def sonar(self, sensors: tuple[Sensor, ...]) -> dict[str, int | None]:
        return await self._body.sonar(sensors)


class Looker:
    """The machine's Sense and the start of its Move with a body a look may leave beside
    the sub-cell the machine believes the robot is on (``home``)."""

    def __init__(self, body: Hardware, sonar: SonarMap, on_step: StepSink) -> None:
        self.marked = MarkedSteps(body, on_step)
        self.sonar = sonar
        self.home: SubCell | None = None  # set while the body stands beside it
        self.came_from: SubCell | None = None  # where the body stood before the last move
        self.back: SubCell | None = None  # the step back out of a cell given up, not made yet
        self.stepped_out: list[SubCell] = []  # entered to look from inside, stepped out of

    async def sense(self, request: Sense, mode: SenseMode, may_hold_body: BodyTest,
                    peer_in: BodyTest | None = None) -> SenseResult:
        pose = self.marked.pose
        if pose is None:
            raise HardwareError("the body's pose is not known yet")
        inside = request.cells[0] == cell_of(self.home or (pose[0], pose[1]))
        if self.home is not None and request.enter:
            # from beside the ray crosses the half the walk does not enter: no HALF from there
            request = replace(request, enter=False)
        # a second look while aside comes back to the same sub-cell beside, so the body is
        # always on home or one step from it (the step held, published or walked later)
        stay = self.home is None
        result = await look(self.marked, self.sonar, request, mode, may_hold_body, stay,
                            peer_in)
        home = self.home or (pose[0], pose[1])
        self.home = None if _sub(self.marked) == home else home
        if self.home is None:
            self.marked.publish()
        if inside and result.statuses[0][1] is not CellStatus.FREE:
            # the machine steps back out (giving the cell up unless a rival's body is in
            # it, planner/ormstc/inside.py): the way in and out were looks
            entered = self.home or (pose[0], pose[1])
            self.marked.mark(entered)
            self.sonar.steps += 1
            self.back = self.came_from
            self.stepped_out.append(entered)
        return result

    def walked(self, to: SubCell) -> bool:
        """After the machine's move to ``to``: True if it was a look step (the step back
        out of a cell looked at from inside), published as one."""
        if to != self.back:
            return False
        self.back = None
        self.marked.mark(to)
        self.sonar.steps += 1
        return True

    async def settle(self, to: SubCell) -> bool:
        """Before the machine's move to ``to``: True if the body stands on ``to`` already
        (the step aside was this move), else bring it back home (a look step) for the move."""
        home, self.home = self.home, None
        self.came_from = home or _sub(self.marked)
        if home is None:
            return False
        if _sub(self.marked) == to:
            self.marked.publish(last_walked=True)
            self.sonar.steps -= 1  # counted as a look step when made
            return True
        await step_back(self.marked, self.sonar, home)
        self.marked.publish()
        return False


def _sub(body: Hardware) -> SubCell:
    if body.pose is None:
        raise HardwareError("the body's pose is not known yet")
    return (body.pose[0], body.pose[1])


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
