"""Seeded floor plans: rooms in a grid of one-cell walls, joined by doors.

    rooms_cells(30, 40, np.random.default_rng(3))   # 30 x 40 cells

Every wall between two neighbouring rooms gets a door (one or two cells wide) if it lies on
a random spanning tree of the rooms, and a door with probability EXTRA_DOOR otherwise, so
every room is reachable and some are reachable two ways. Walls run the whole width or
height of the plan; the cells where walls cross stay blocked.
"""

from __future__ import annotations

import numpy as np

from planner.types import BoolArray

ROOM = (4, 8)  # room side in cells (inclusive range)
EXTRA_DOOR = 0.3  # chance of a door in a wall off the spanning tree
_DOOR = (1, 2)  # door width in cells (inclusive range)


def rooms_cells(rows: int, cols: int, rng: np.random.Generator) -> BoolArray:
    """Free cells of a rows x cols floor plan (at least 1 x 1: one room, no wall)."""
    if rows < 1 or cols < 1:
        raise ValueError(f"a floor plan needs at least 1 x 1 cells, got {rows} x {cols}")
    row_spans = _spans(rows, rng)
    col_spans = _spans(cols, rng)
    cells = np.zeros((rows, cols), dtype=bool)
    for r0, r1 in row_spans:
        for c0, c1 in col_spans:
            cells[r0:r1, c0:c1] = True
    walls = _walls(len(row_spans), len(col_spans))
    tree = _spanning_tree(len(row_spans) * len(col_spans), walls, rng)
    for index, (a, b) in enumerate(walls):
        if index in tree or rng.random() < EXTRA_DOOR:
            _open_door(cells, row_spans, col_spans, a, b, len(col_spans), rng)
    return cells


def _spans(length: int, rng: np.random.Generator) -> list[tuple[int, int]]:
    """Room spans [a, b) along one axis, one wall cell between neighbours."""
    spans = []
    at = 0
    while at < length:
        size = int(rng.integers(ROOM[0], ROOM[1] + 1))
        end = min(length, at + size)
        if length - end <= ROOM[0]:  # no room for one more room: this one takes the rest
            end = length
        spans.append((at, end))
        at = end + 1
    return spans


def _walls(rows: int, cols: int) -> list[tuple[int, int]]:
    """Pairs of neighbouring rooms (flat indices, row-major), the lower index first."""
    pairs = []
    for r in range(rows):
        for c in range(cols):
            here = r * cols + c
            if c + 1 < cols:
                pairs.append((here, here + 1))
            if r + 1 < rows:
                pairs.append((here, here + cols))
    return pairs


def _spanning_tree(rooms: int, walls: list[tuple[int, int]],
                   rng: np.random.Generator) -> set[int]:
    """Indices of walls forming a random spanning tree of the rooms (Kruskal, shuffled)."""
    parent = list(range(rooms))

    def root(x: int) -> int:
        while parent[x] != x:
            parent[x] = parent[parent[x]]
            x = parent[x]
        return x

    chosen = set()
    for index in rng.permutation(len(walls)):
        a, b = walls[int(index)]
        ra, rb = root(a), root(b)
        if ra != rb:
            parent[ra] = rb
            chosen.add(int(index))
    return chosen


def _open_door(cells: BoolArray, row_spans: list[tuple[int, int]],
               col_spans: list[tuple[int, int]], a: int, b: int, cols: int,
               rng: np.random.Generator) -> None:
    ra, ca = divmod(a, cols)
    rb = b // cols
    width = int(rng.integers(_DOOR[0], _DOOR[1] + 1))
    if ra == rb:  # side by side: the wall is the column after room a
        wall = col_spans[ca][1]
        lo, hi = row_spans[ra]
        at = int(rng.integers(lo, max(lo + 1, hi - width + 1)))
        cells[at:min(hi, at + width), wall] = True
    else:  # one above the other: the wall is the row after room a
        wall = row_spans[ra][1]
        lo, hi = col_spans[ca]
        at = int(rng.integers(lo, max(lo + 1, hi - width + 1)))
        cells[wall, at:min(hi, at + width)] = True
