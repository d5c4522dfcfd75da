"""simhw's hardware API as the ORMSTC driver uses it: one body, one command at a time.

Each command is a query on ``hw/<r>/cmd`` answered when the motion is over in sim time, sent
through agent.core.hw_link with the retry policy every agent shares (lost replies, a router
restart: re-asked until the link's deadline, a motion re-sent only if the pose shows it was
not done). Unlike agent.offline.hardware (the offline agent's client) a bump is returned, not
retried: the ORMSTC machine backs off and retries itself. Sense commands name their sonars;
when simhw runs in one-at-a-time mode (it rejects several), every later sense names one.

:func:`look` carries out the machine's ``Sense`` with that body and agent.ormstc.sensing's
geometry: a thin ray sees one half of a neighbouring cell, so when the other half was never
seen free the robot steps to the sub-cell beside it (its own cell), reads the same direction
with a side sonar and steps back (docs/ormstc.md, "Sensing with a thin sonar"). Where the
machine allows it (``Sense.enter``) the other half is instead seen from inside the cell
after growing into it (:func:`look_inside`, planner/ormstc/inside.py).
"""

from __future__ import annotations

from typing import Protocol, cast

from agent.core.errors import HardwareError
from agent.core.hw_link import HwLink, facing, standing_on, turns
from agent.ormstc.sensing import (
    HEADING_DELTA,
    BodyTest,
    SonarMap,
    beside,
    cell_of,
    cells_in_view,
    direction_of,
    direction_to,
    judge,
    sensor_for,
    sub_cells,
)
from bus.bridge import Bus
from bus.messages import HwAction, HwReply, Sensor
from planner.ormstc.types import Cell, CellStatus, Sense, SenseMode, SenseResult, SubCell


class Body:
    """simhw's hardware API for one robot: commands are queries answered after the motion."""

    def __init__(self, bus: Bus, robot: int, incarnation: int, timeout: float) -> None:
        self.link = HwLink(bus, robot, incarnation, timeout=timeout, on_reply=self._seen)
        self.robot, self.incarnation, self.timeout = robot, incarnation, timeout
        self.pose: tuple[int, int, int] | None = None
        self.one_sonar = False  # set once simhw says one sonar per command

    def _seen(self, reply: HwReply) -> None:
        self.pose = reply.pose

    async def must(self, action: HwAction, sensors: tuple[Sensor, ...] = ()) -> HwReply:
        """A command that must answer ok (sense, pose, turns)."""
        if action in ("turn_left", "turn_right"):
            assert self.pose is not None
            want = (self.pose[2] + (1 if action == "turn_right" else -1)) % 4
            reply = await self.link.motion(action, facing(want))
        else:
            reply = await self.link.ask(action, sensors)
        if reply.status != "ok":
            raise HardwareError(f"robot {self.robot}: '{action}' answered {reply.status}: "
                                f"{reply.message}")
        return reply

    async def wait_for_pose(self, patience: float) -> tuple[int, int, int]:
        return await self.link.wait_for_pose(patience)

    async def step(self) -> HwReply:
        """One forward step: ``ok``, ``bumped`` or a failure status (never a lost reply)."""
        assert self.pose is not None
        r, c, heading = self.pose
        dr, dc = HEADING_DELTA[heading]
        return await self.link.motion("forward", standing_on((r + dr, c + dc)))

    async def forward(self) -> bool:
        """One step ahead: True if the body moved, False if it bumped."""
        reply = await self.step()
        if reply.status not in ("ok", "bumped"):
            raise HardwareError(f"robot {self.robot}: forward answered {reply.status}: "
                                f"{reply.message}")
        return reply.status == "ok"

    async def face(self, heading: int) -> None:
        assert self.pose is not None
        action: HwAction
        for action in turns(self.pose[2], heading):
            await self.must(action)

    async def sonar(self, sensors: tuple[Sensor, ...]) -> dict[str, int | None]:
        """Ranges of ``sensors``: one command, or one each in one-at-a-time mode."""
        if len(sensors) > 1 and not self.one_sonar:
            reply = await self.link.ask("sense", sensors)
            if reply.status == "ok":
                return dict(reply.sonar)
            if reply.status != "rejected":
                raise HardwareError(f"robot {self.robot}: sense answered {reply.status}")
            self.one_sonar = True  # simhw runs --sonar-mode one-at-a-time
        ranges: dict[str, int | None] = {}
        for sensor in sensors:
            ranges.update((await self.must("sense", (sensor,))).sonar)
        return ranges


class Hardware(Protocol):
    """What :func:`look` needs of a body (``Body``, or a test's stand-in)."""

    pose: tuple[int, int, int] | None

    async def face(self, heading: int) -> None: ...

    async def forward(self) -> bool: ...

    async def sonar(self, sensors: tuple[Sensor, ...]) -> dict[str, int | None]: ...


_ALL_SONARS: tuple[Sensor, ...] = ("front", "left", "right")


async def look(body: Hardware, sonar: SonarMap, request: Sense, mode: SenseMode,
               may_hold_body: BodyTest, stay: bool = False,
               peer_in: BodyTest | None = None) -> SenseResult:
    """The answer to ``request``: no cell is FREE unless both of its halves were seen free.

    The target gets an extra look from the sub-cell beside when its other half is unknown;
    another requested cell with an unknown half is left out (the machine then senses it
    again when it decides it). All three sonars are read whatever was asked (one command
    each in one-at-a-time mode): a reading takes 0.1 s of simhw time, a step aside and back
    about 8 s, and the extra rays spare many of those (docs/ormstc.md). With ``stay`` the
    body is left on the sub-cell beside, if it stepped there: that sub-cell is the walk's
    next one unless the robot grows into the target (agent.ormstc.looks.Looker steps back
    only then).
    """
    pose = _pose(body)
    pos: SubCell = (pose[0], pose[1])
    here, target = cell_of(pos), request.cells[0]
    if target == here:
        return await look_inside(body, sonar, target, may_hold_body, stay, peer_in)
    if sensor_for(pose[2], direction_to(here, target)) is None:
        await _face(body, (pose[2] + 1) % 4, sonar)  # the cell is behind
    heading = _pose(body)[2]
    view = cells_in_view(here, heading, request.cells if mode is SenseMode.ALL else (target,))
    ranges = await _read(body, sonar, _ALL_SONARS, pos, heading, may_hold_body)
    statuses: list[tuple[Cell, CellStatus]] = []
    for cell, sensor in view.items():
        direction = direction_of(heading, sensor)
        status = judge(cell, pos, direction, ranges.get(sensor), sonar, may_hold_body)
        if status is None and cell == target and request.enter:
            status = CellStatus.HALF  # the near half, which the walk enters, is free
        elif status is None and cell == target:
            status = await _look_beside(body, sonar, target, pos, direction, may_hold_body,
                                        stay)
        if status is not None:
            statuses.append((cell, status))
    return SenseResult(tuple(statuses))


async def _look_beside(body: Hardware, sonar: SonarMap, target: Cell, pos: SubCell,
                       direction: int, may_hold_body: BodyTest, stay: bool) -> CellStatus:
    """Step to the sub-cell beside ``pos``, look along ``direction`` at ``target``, step back
    unless ``stay``."""
    side = beside(pos, direction)
    aside = direction_to(pos, side)
    sonar.beside_looks += 1
    await _face(body, aside, sonar)
    if not await body.forward():
        # only a body can stand in the robot's own cell: report one, nothing is remembered
        return CellStatus.ROBOT
    sonar.steps += 1
    sensor = cast(Sensor, sensor_for(aside, direction))  # a side sonar: never behind
    ranges = await _read(body, sonar, _ALL_SONARS, side, aside, may_hold_body)
    status = judge(target, side, direction, ranges.get(sensor), sonar, may_hold_body)
    if not stay:
        await step_back(body, sonar, pos)
    # both halves are in the memory now, so None cannot come back; if it did, never say FREE
    return CellStatus.ROBOT if status is None else status


async def look_inside(body: Hardware, sonar: SonarMap, cell: Cell, may_hold_body: BodyTest,
                      stay: bool = False, peer_in: BodyTest | None = None) -> SenseResult:
    """The status of ``cell``, which the body has just entered (planner/ormstc/inside.py).

    The robot owns the cell, so no other body can be in it unless ``peer_in`` says a peer
    may be (it claimed or owns the cell too, or its pose lies there: a conflict): a sub-cell
    a ray shows blocked there is an obstacle, or else unknown (ROBOT). The sonars read where
    the body stands see the far sub-cell next to it; the one diagonal to it is seen from
    the next sub-cell of the cell, which the walk enters next when the cell is free (so
    with ``stay`` the body is left there; the Looker counts the step).
    """
    def elsewhere(other: Cell) -> bool:
        if other == cell:
            return peer_in is not None and peer_in(other)
        return may_hold_body(other)

    status = _inside(cell, sonar)
    if status is None:
        pose = _pose(body)
        await _read(body, sonar, _ALL_SONARS, (pose[0], pose[1]), pose[2], elsewhere)
        status = _inside(cell, sonar)
    if status is None:
        pose = _pose(body)
        pos: SubCell = (pose[0], pose[1])
        ahead = (pos[0] + HEADING_DELTA[pose[2]][0], pos[1] + HEADING_DELTA[pose[2]][1])
        nxt = ahead if cell_of(ahead) == cell else beside(pos, (pose[2] + 1) % 4)
        await _face(body, direction_to(pos, nxt), sonar)
        if not await body.forward():
            return SenseResult(((cell, CellStatus.ROBOT),))  # a body in the way (inside.py)
        sonar.steps += 1
        heading = _pose(body)[2]
        await _read(body, sonar, _ALL_SONARS, nxt, heading, elsewhere)
        status = _inside(cell, sonar)
        if not stay:
            await step_back(body, sonar, pos)
    return SenseResult(((cell, CellStatus.ROBOT if status is None else status),))


def _inside(cell: Cell, sonar: SonarMap) -> CellStatus | None:
    subs = sub_cells(cell)
    if any(sub in sonar.static for sub in subs):
        return CellStatus.OBSTACLE
    if all(sub in sonar.free for sub in subs):
        return CellStatus.FREE
    return None


async def step_back(body: Hardware, sonar: SonarMap, to: SubCell) -> None:
    """Step from the sub-cell beside back to ``to`` in the robot's own cell."""
    pose = _pose(body)
    await _face(body, direction_to((pose[0], pose[1]), to), sonar)
    if not await body.forward():
        raise HardwareError(f"cannot step back to {to} after looking from beside: "
                            "something entered the robot's own cell")
    sonar.steps += 1


async def _read(body: Hardware, sonar: SonarMap, sensors: tuple[Sensor, ...], pos: SubCell,
                heading: int, may_hold_body: BodyTest) -> dict[str, int | None]:
    ranges = await body.sonar(sensors)
    sonar.readings += len(sensors)
    for sensor in sensors:
        sonar.record(pos, direction_of(heading, sensor), ranges.get(sensor), may_hold_body)
    return ranges


async def _face(body: Hardware, heading: int, sonar: SonarMap) -> None:
    turns = (heading - _pose(body)[2]) % 4
    sonar.turns += 2 if turns == 2 else min(turns, 1)
    await body.face(heading)


def _pose(body: Hardware) -> tuple[int, int, int]:
    if body.pose is None:
        raise HardwareError("the body's pose is not known yet")
    return body.pose
