"""Sonar geometry of the ORMSTC driver: how to look at a neighbouring cell, what a reading says.

simhw's sonar is a thin ray along one of the four headings from the body's own sub-cell
(docs/simhw.md), so it crosses one row (or column) of a neighbouring cell: the two sub-cells
at distance ``near`` and ``near + 1``, where ``near`` is 1 or 2 depending on how many of the
robot's own sub-cells lie ahead. Whatever a ray shows is remembered in a :class:`SonarMap`;
the other half of the cell is judged from that memory, and when a sub-cell of it was never
seen free the cell is *unknown* (``judge`` gives None), never FREE: an obstacle that fills
only part of a cell may lie there. The other half is seen by the same ray from the sub-cell
beside the robot in its own cell (``beside``), which agent.ormstc.body steps to.

A blocked sub-cell is a robot body or a static obstacle; the ray cannot tell which. Bodies
only stand in cells their robot owns or is claiming, and ownership is announced before a body
enters, so a blocked sub-cell in a cell nobody ever owned or claimed is an obstacle, and one
in a cell someone did (or where a peer's heartbeat pose lies) is reported as a body. Pure: no
I/O, no clock.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterable
from dataclasses import dataclass, field

from planner.geometry import Heading, cell_of
from planner.ormstc.knowledge import Knowledge
from planner.ormstc.types import Cell, CellStatus, SubCell

# planner.geometry's numbering (clockwise from north, a right turn is +1), indexable by int
HEADING_DELTA: tuple[SubCell, ...] = tuple(h.delta for h in Heading)
_RELATIVE_SENSOR = {0: "front", 1: "right", 3: "left"}

BodyTest = Callable[[Cell], bool]
Ray = tuple[int, int, int, int]  # row, col read from, direction, sub-cells ahead shown free


def direction_to(cell: Cell, other: Cell) -> int:
    """The heading of the step from ``cell`` to the 4-adjacent ``other`` (cells or sub-cells)."""
    delta = (other[0] - cell[0], other[1] - cell[1])
    if delta not in HEADING_DELTA:
        raise ValueError(f"cell {other} is not next to cell {cell}")
    return HEADING_DELTA.index(delta)


def sensor_for(heading: int, direction: int) -> str | None:
    """The sonar ("front", "left", "right") looking along ``direction``; None if behind."""
    return _RELATIVE_SENSOR.get((direction - heading) % 4)


def direction_of(heading: int, sensor: str) -> int:
    offset = {"front": 0, "right": 1, "left": 3}[sensor]
    return (heading + offset) % 4


def ahead(pos: SubCell, direction: int, steps: int) -> SubCell:
    dr, dc = HEADING_DELTA[direction]
    return (pos[0] + steps * dr, pos[1] + steps * dc)


def near_distance(pos: SubCell, direction: int) -> int:
    """Ray distance from ``pos`` to the first sub-cell of the neighbouring cell that way."""
    row, col = pos[0] & 1, pos[1] & 1
    inside = (row, 1 - col, 1 - row, col)[direction]  # own sub-cells still ahead: N E S W
    return inside + 1


def sub_cells(cell: Cell) -> tuple[SubCell, ...]:
    r, c = 2 * cell[0], 2 * cell[1]
    return ((r, c), (r, c + 1), (r + 1, c), (r + 1, c + 1))


@dataclass
class SonarMap:
    """Sub-cells rays have shown free, and those shown blocked where no body can be."""

    max_range: int = 8
    free: set[SubCell] = field(default_factory=set)
    static: set[SubCell] = field(default_factory=set)  # obstacles for certain
    # what peers' rays showed free (SonarRays): used only for cells no body can be in, as
    # the peer's reading may be older than a body's arrival
    shared: set[SubCell] = field(default_factory=set)
    rays: list[Ray] = field(default_factory=list)  # own rays recorded, not yet told to peers
    # what looking cost (agent.ormstc.body.look counts): sonar readings, looks from the
    # sub-cell beside, the forward steps they made (two each unless a body was in the way)
    # and the quarter turns made only to look
    readings: int = 0
    glance_readings: int = 0  # of the readings, those taken after a move (agent.ormstc.looks)
    beside_looks: int = 0
    steps: int = 0
    turns: int = 0

    def record(self, pos: SubCell, direction: int, reading: int | None,
               may_hold_body: BodyTest) -> SubCell | None:
        """Remember one ray; return the blocked sub-cell it hit, if any."""
        last = self.max_range if reading is None else reading - 1
        for step in range(1, last + 1):
            self.free.add(ahead(pos, direction, step))
        if last > 0:
            self.rays.append((pos[0], pos[1], direction, last))
        if reading is None:
            return None
        hit = ahead(pos, direction, reading)
        if not may_hold_body(cell_of(hit)):
            self.static.add(hit)
            self.free.discard(hit)
        return hit


    def hear(self, rays: Iterable[Ray]) -> None:
        """Take in what a peer's rays showed free."""
        for row, col, direction, last in rays:
            if 0 <= direction < 4 and 0 < last <= self.max_range:
                self.shared.update(ahead((row, col), direction, step)
                                   for step in range(1, last + 1))

    def told(self) -> tuple[Ray, ...]:
        """The rays recorded since the last call, for peers."""
        rays, self.rays = tuple(self.rays), []
        return rays


def peer_may_be_in(cell: Cell, me: int, know: Knowledge | None,
                   peer_cells: Collection[Cell]) -> bool:
    """Whether a peer's body can stand in ``cell``, a cell robot ``me`` owns: a peer claimed
    or owns it too (a conflict, planner/ormstc/conflicts.py), or its last pose lies there.
    A hit inside an own cell is an obstacle only where this is False (body.look_inside)."""
    if cell in peer_cells:
        return True
    if know is None:
        return False
    return (any(r != me for r in know.owners.get(cell, ()))
            or any(r != me for r in know.claims.pending.get(cell, ())))


def shows_news(sonar: SonarMap, pos: SubCell, direction: int) -> bool:
    """Whether a ray from ``pos`` along ``direction`` could cross a sub-cell never seen: one
    neither seen free nor known blocked before the first known obstacle on the way."""
    for step in range(1, sonar.max_range + 1):
        sub = ahead(pos, direction, step)
        if sub in sonar.static:
            return False
        if sub not in sonar.free:
            return True
    return False


def judge(cell: Cell, pos: SubCell, direction: int, reading: int | None, sonar: SonarMap,
          may_hold_body: BodyTest) -> CellStatus | None:
    """Status of the neighbouring ``cell`` from a ray along ``direction`` read at ``pos``
    (already recorded in ``sonar``); None while a sub-cell of the unseen half is unknown.

    The ray's half decides first (a hit inside the cell: obstacle or body, see the module
    doc). The cell is FREE only if every one of its sub-cells was once seen free — a static
    world never blocks a sub-cell a ray has passed through; where no body can be, by this
    robot's rays or a peer's (``shared``). The unseen half is an obstacle if a ray once
    showed a static obstacle there and no body can be in the cell.
    """
    near = near_distance(pos, direction)
    if reading is not None and reading < near:
        return CellStatus.ROBOT  # something inside the robot's own cell can only be a body
    if reading is not None and reading <= near + 1:
        return CellStatus.ROBOT if may_hold_body(cell) else CellStatus.OBSTACLE
    subs = sub_cells(cell)
    if all(sub in sonar.free for sub in subs):
        return CellStatus.FREE
    if may_hold_body(cell):
        # a remembered hit may have been a body since gone; a peer's ray too old to show one
        return None
    if any(sub in sonar.static for sub in subs):
        return CellStatus.OBSTACLE
    if all(sub in sonar.free or sub in sonar.shared for sub in subs):
        return CellStatus.FREE
    return None


def beside(pos: SubCell, direction: int) -> SubCell:
    """The sub-cell of ``pos``'s cell next to ``pos`` whose ray along ``direction`` crosses
    the other half of the neighbouring cell (the other row or column of the cell)."""
    if direction % 2 == 0:  # N / S: the rays run along columns
        return (pos[0], pos[1] ^ 1)
    return (pos[0] ^ 1, pos[1])


def cells_in_view(cell: Cell, heading: int, wanted: Iterable[Cell]) -> dict[Cell, str]:
    """Which sonar sees each ``wanted`` neighbour of ``cell`` without turning."""
    out: dict[Cell, str] = {}
    for other in wanted:
        sensor = sensor_for(heading, direction_to(cell, other))
        if sensor is not None:
            out[other] = sensor
    return out
