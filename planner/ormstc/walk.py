"""Geometry of the online STC walk: sides, neighbours, successor and predecessor sub-cells.

The walk is the repository's STC convention (planner/cycle.py): counter-clockwise as drawn
with rows going down, the tree on the walker's left. The papers draw y upwards and say
"clockwise, right side of the tree edge": the same walk seen in a mirror. Every sub-cell
faces one side of its cell (top-left: west, bottom-left: south, bottom-right: east,
top-right: north); that side is the neighbour the DFS decides on while standing there.
"""

from __future__ import annotations

from collections.abc import Callable

from planner.geometry import WALK_SIDES, Cell, SubCell

NORTH, WEST, SOUTH, EAST = 0, 1, 2, 3  # side numbers: indices into geometry.WALK_SIDES
DELTA: tuple[SubCell, ...] = tuple(heading.delta for heading in WALK_SIDES)
# side faced by the sub-cell at (row % 2, col % 2)
_SIDE = {(0, 0): WEST, (1, 0): SOUTH, (1, 1): EAST, (0, 1): NORTH}
_SUB_OF_SIDE = {side: offset for offset, side in _SIDE.items()}
# the same, indexed by (row % 2) * 2 + col % 2: for loops that cannot afford a tuple and a hash
SIDE_AT: tuple[int, ...] = tuple(_SIDE[(i >> 1, i & 1)] for i in range(4))

EdgeTest = Callable[[Cell, int], bool]


def cell_of(sub: SubCell) -> Cell:
    return (sub[0] >> 1, sub[1] >> 1)


def side_of(sub: SubCell) -> int:
    return _SIDE[(sub[0] & 1, sub[1] & 1)]


def neighbour(cell: Cell, side: int) -> Cell:
    dr, dc = DELTA[side]
    return (cell[0] + dr, cell[1] + dc)


def sub_facing(cell: Cell, side: int) -> SubCell:
    """The sub-cell of ``cell`` that faces ``side``."""
    dr, dc = _SUB_OF_SIDE[side]
    return (2 * cell[0] + dr, 2 * cell[1] + dc)


def side_towards(cell: Cell, other: Cell) -> int:
    """The side of ``cell`` that borders the 4-adjacent ``other``."""
    return DELTA.index((other[0] - cell[0], other[1] - cell[1]))


def arrival_side(sub: SubCell) -> int:
    """The side a walk entering a cell at ``sub`` comes from (Fig. 1's W for a start)."""
    return (side_of(sub) - 1) % 4


def successor(sub: SubCell, has_edge: EdgeTest) -> SubCell:
    """Next sub-cell of the walk: cross the faced side if it is a tree edge, else turn."""
    side = side_of(sub)
    step = DELTA[side] if has_edge(cell_of(sub), side) else DELTA[(side + 1) % 4]
    return (sub[0] + step[0], sub[1] + step[1])


def predecessor(sub: SubCell, has_edge: EdgeTest) -> SubCell:
    """Previous sub-cell of the walk (the successor's inverse)."""
    side = side_of(sub)
    before = (side - 1) % 4
    if has_edge(cell_of(sub), before):
        step = DELTA[before]
    else:
        back = DELTA[side]
        step = (-back[0], -back[1])
    return (sub[0] + step[0], sub[1] + step[1])


def walk_index(start: SubCell, has_edge: EdgeTest, n: int) -> dict[SubCell, int]:
    """Steps from ``start`` to each of the next ``n`` sub-cells of the walk (a cycle of n)."""
    index: dict[SubCell, int] = {}
    pos = start
    for i in range(n):
        index[pos] = i
        pos = successor(pos, has_edge)
    return index


def initial_arrival(start: SubCell) -> Cell:
    """Fig. 1: the cell W the robot is deemed to have arrived from, given its start."""
    return neighbour(cell_of(start), arrival_side(start))
