"""ORMSTC on the wire (docs/ormstc.md, "ORMSTC on the wire"): the twins of planner.ormstc's
messages.

``incarnation`` is the sender's life and ``seq`` numbers that life's ORMSTC messages 1, 2, ...
over all kinds (gaps are visible). Cells are (row, col) of 2 x 2 sub-cell cells; a sub-cell
is (row, col) in sub-cells.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from bus.messages.base import Cell, SubCell


@dataclass(frozen=True)
class OrmstcStart:
    """Alg. 1: robot's start sub-cell; its cell is the robot's from now on."""

    KIND: ClassVar[str] = "ormstc_start"
    robot: int
    incarnation: int
    seq: int
    sub: SubCell


@dataclass(frozen=True)
class OrmstcClaim:
    """Robot wants to grow into ``cell``; ``covered`` = cells it owns (FEWEST priority)."""

    KIND: ClassVar[str] = "ormstc_claim"
    robot: int
    incarnation: int
    seq: int
    cell: Cell
    covered: int


@dataclass(frozen=True)
class OrmstcTreeEdge:
    """Robot built the tree edge ``parent`` -> ``child``: ``child`` is its cell."""

    KIND: ClassVar[str] = "ormstc_tree"
    robot: int
    incarnation: int
    seq: int
    parent: Cell
    child: Cell


@dataclass(frozen=True)
class OrmstcConnection:
    """Robot's cell ``mine`` borders ``theirs`` of robot ``peer`` (monitoring only)."""

    KIND: ClassVar[str] = "ormstc_conn"
    robot: int
    incarnation: int
    seq: int
    peer: int
    mine: Cell
    theirs: Cell


@dataclass(frozen=True)
class OrmstcDeadRobot:
    """Robot found robot ``dead`` dead: its cells are free again."""

    KIND: ClassVar[str] = "ormstc_dead"
    robot: int
    incarnation: int
    seq: int
    dead: int


@dataclass(frozen=True)
class OrmstcCompletion:
    """Robot covered every cell it can reach (``cells`` of its own)."""

    KIND: ClassVar[str] = "ormstc_done"
    robot: int
    incarnation: int
    seq: int
    cells: int


@dataclass(frozen=True)
class OrmstcWithdrawal:
    """Robot takes back its completion to cover cells robot ``peer`` no longer holds."""

    KIND: ClassVar[str] = "ormstc_withdraw"
    robot: int
    incarnation: int
    seq: int
    peer: int


@dataclass(frozen=True)
class OrmstcRetraction:
    """Robot takes back its tree edge ``parent`` -> ``child``: it found an obstacle or a dead
    robot's body in ``child`` from inside. For monitors: peers keep the cell as the robot's."""

    KIND: ClassVar[str] = "ormstc_retract"
    robot: int
    incarnation: int
    seq: int
    parent: Cell
    child: Cell


OrmstcWire = (OrmstcStart | OrmstcClaim | OrmstcTreeEdge | OrmstcConnection | OrmstcDeadRobot
              | OrmstcCompletion | OrmstcWithdrawal | OrmstcRetraction)

ORMSTC_MESSAGES: tuple[type[Any], ...] = (
    OrmstcStart, OrmstcClaim, OrmstcTreeEdge, OrmstcConnection, OrmstcDeadRobot,
    OrmstcCompletion, OrmstcWithdrawal, OrmstcRetraction)


@dataclass(frozen=True)
class SonarRays:
    """Rays an ORMSTC robot's sonar read (not a machine message: no ``seq``, best effort).
    Per ray: the sub-cell it was read from, its heading (clockwise from north) and how many
    sub-cells ahead it showed free. A static world never blocks a sub-cell once seen free,
    so peers add these to what they know and look from beside less often; the hit is not
    sent (only the sender can tell a body from an obstacle by what it knows)."""

    KIND: ClassVar[str] = "sonar_rays"
    robot: int
    incarnation: int
    rays: tuple[tuple[int, int, int, int], ...]
