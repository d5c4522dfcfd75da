"""Robots that start in the same cell: split it in halves, or hang it off one robot.

A cell reached from a neighbour (its *anchor*) is walked by the STC cycle in a fixed order:
in at one sub-cell on the anchor's side, round the three others, out at the second sub-cell
on the anchor's side. Keeping only the anchor-side half keeps the walk closed; dropping the
sub-cells next to the owner's start along that walk leaves an open walk that still starts at
the owner. That is the whole trick: every choice below is checked against that order.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from itertools import product

from planner.geometry import sub_cells_of
from planner.types import Cell, SubCell

# (dr, dc) from the cell to its anchor
SIDES: tuple[tuple[int, int], ...] = ((0, -1), (0, 1), (-1, 0), (1, 0))


def walk_order(cell: Cell, side: tuple[int, int] | None) -> tuple[SubCell, ...]:
    """The cell's sub-cells in STC order when entered from the neighbour at ``side``.

    With ``side`` None (a cell alone) it is the cell's own counter-clockwise 4-cycle.
    """
    tl, bl, br, tr = sub_cells_of(cell)
    if side == (0, 1):
        return (tr, tl, bl, br)
    if side == (0, -1):
        return (bl, br, tr, tl)
    if side == (1, 0):
        return (br, tr, tl, bl)
    return (tl, bl, br, tr)


def near_half(cell: Cell, side: tuple[int, int]) -> tuple[SubCell, SubCell]:
    """The two sub-cells of ``cell`` on the side of its neighbour at ``side``."""
    order = walk_order(cell, side)
    return (order[0], order[3])


_TREE = (-1, -1)  # stands for "the rest of the region" in a leaf's circular walk


def open_walk_ok(cell: Cell, side: tuple[int, int] | None, keep: set[SubCell],
                 start: SubCell) -> bool:
    """Whether one open walk from ``start`` covers ``keep`` (and the rest of the region).

    True when the kept items follow ``start`` consecutively, one way or the other round the
    circular walk (the cell's sub-cells, then the region behind the anchor).
    """
    circle = list(walk_order(cell, side)) + ([_TREE] if side is not None else [])
    wanted = set(keep) | ({_TREE} if side is not None else set())
    if start not in wanted:
        return False
    i = circle.index(start)
    m = len(circle)
    for step in (1, -1):
        run = {circle[(i + step * j) % m] for j in range(len(wanted))}
        if run == wanted:
            return True
    return False


@dataclass(frozen=True)
class Share:
    """How one shared cell is divided: per robot its kept sub-cells and anchor side (or None)."""

    parts: tuple[tuple[int, tuple[SubCell, ...], tuple[int, int] | None], ...]

    def score(self) -> tuple[int, int]:
        anchored = sum(1 for _, _, side in self.parts if side is not None)
        return (anchored, -max(len(keep) for _, keep, _ in self.parts))


def share_cell(cell: Cell, robots: Sequence[int], starts: Sequence[SubCell],
               claimable: Callable[[Cell], bool]) -> Share:
    """The best division of ``cell`` among ``robots`` (two to four) that all start in it.

    Brute force over every assignment of the free sub-cells to robots and every choice of
    anchor side per robot (at most a few hundred cases): each robot's part must be one open
    walk from its start (see open_walk_ok). Preferred: as many anchored robots as possible,
    since only they can grow into the rest of the map.
    """
    r, c = cell
    subs = sub_cells_of(cell)
    own = {starts[rb]: rb for rb in robots}
    loose = [s for s in subs if s not in own]
    sides: list[tuple[int, int] | None] = [
        s for s in SIDES if claimable((r + s[0], c + s[1]))]
    best: Share | None = None
    for owners in product(robots, repeat=len(loose)):
        keep = {rb: [starts[rb]] for rb in robots}
        for sub, rb in zip(loose, owners, strict=True):
            keep[rb].append(sub)
        choices = [[side for side in [*sides, None]
                    if open_walk_ok(cell, side, set(keep[rb]), starts[rb])] for rb in robots]
        for picked in product(*choices):
            used = [side for side in picked if side is not None]
            if len(used) != len(set(used)):
                continue
            share = Share(tuple(
                (rb, tuple(s for s in walk_order(cell, side) if s in keep[rb]), side)
                for rb, side in zip(robots, picked, strict=True)))
            if best is None or share.score() > best.score():
                best = share
    # Two robots at the ends of one edge of the 4-cycle can always split it in two open
    # walks without anchors, so some division always exists.
    assert best is not None, f"no division of shared cell {cell}"
    return best
