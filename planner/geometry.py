"""The one geometry module: sub-cells, cells, headings and poses, and one direction numbering.

Coordinates are (row, col), rows growing downwards as in images and map files. A *sub-cell*
is one tool-sized square of the fine grid; a *cell* is the 2 x 2 block of sub-cells
(2r..2r+1, 2c..2c+1). Headings are numbered clockwise as a compass: 0 = north (row - 1),
1 = east (col + 1), 2 = south, 3 = west; a right turn is +1 mod 4. This is the numbering on the
wire and in simhw. The ORMSTC walk visits a cell's sides counter-clockwise on screen: that
order is :data:`WALK_SIDES`, expressed in headings, not a second set of bare numbers.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum, IntEnum

SubCell = tuple[int, int]
Cell = tuple[int, int]


class Side(Enum):
    """A turn, or a sonar beside the front one."""

    LEFT = "left"
    RIGHT = "right"


class Heading(IntEnum):
    N = 0
    E = 1
    S = 2
    W = 3

    @property
    def delta(self) -> SubCell:
        """One sub-cell step in this heading, as (d_row, d_col)."""
        return _DELTAS[self]

    @classmethod
    def from_delta(cls, delta: SubCell) -> Heading:
        """The heading of a 4-neighbour step (KeyError for anything else)."""
        return _OF_DELTA[delta]

    def turned(self, side: Side) -> Heading:
        return Heading((self + (1 if side is Side.RIGHT else -1)) % 4)

    def towards(self, sensor: str) -> Heading:
        """The heading a sonar looks along: "front", "left" or "right" of this heading."""
        if sensor == "front":
            return self
        return self.turned(Side.LEFT if sensor == "left" else Side.RIGHT)


_DELTAS: dict[Heading, SubCell] = {
    Heading.N: (-1, 0), Heading.E: (0, 1), Heading.S: (1, 0), Heading.W: (0, -1)}
_OF_DELTA: dict[SubCell, Heading] = {delta: heading for heading, delta in _DELTAS.items()}
STEPS: frozenset[SubCell] = frozenset(_DELTAS.values())

# The ORMSTC walk's side order (counter-clockwise on screen): side i of a cell is the
# neighbour in heading WALK_SIDES[i].
WALK_SIDES: tuple[Heading, ...] = (Heading.N, Heading.W, Heading.S, Heading.E)


@dataclass(frozen=True)
class Pose:
    """A body on a sub-cell, facing a heading."""

    row: int
    col: int
    heading: Heading = Heading.N

    @property
    def sub(self) -> SubCell:
        return (self.row, self.col)

    def ahead(self, steps: int = 1) -> SubCell:
        dr, dc = self.heading.delta
        return (self.row + steps * dr, self.col + steps * dc)

    def as_tuple(self) -> tuple[int, int, int]:
        return (self.row, self.col, int(self.heading))


def cell_of(sub: SubCell) -> Cell:
    return (sub[0] // 2, sub[1] // 2)


def sub_cells_of(cell: Cell) -> tuple[SubCell, SubCell, SubCell, SubCell]:
    """The four sub-cells of a cell: top-left, bottom-left, bottom-right, top-right."""
    r, c = 2 * cell[0], 2 * cell[1]
    return ((r, c), (r + 1, c), (r + 1, c + 1), (r, c + 1))
