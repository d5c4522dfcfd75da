"""Each robot's walk: the STC cycle of its own region, opened at its start.

The region's tree is a turn-averse minimum spanning tree of its whole cells (planner.trees,
kind "kruskal") with every leaf cell hung off its anchor. Its STC cycle, started at the
robot's sub-cell, is filtered down to the region's sub-cells: dropping the far half of a
leaf keeps consecutive sub-cells 4-adjacent, and sub-cells handed to a robot that shares the
start cell sit next to the start, so the cycle read forwards or backwards is one open walk
of size - 1 moves with no sub-cell visited twice.
"""

from __future__ import annotations

import numpy as np

from planner.balanced.types import Region
from planner.cycle import stc_cycle
from planner.grid import expand
from planner.trees import build_tree
from planner.types import IntArray, SpanningTree, SubCell


def region_tree(region: Region, origin: tuple[int, int], shape: tuple[int, int],
                seed: int) -> SpanningTree:
    """The region's tree on a crop of the coarse grid with top-left cell ``origin``."""
    r0, c0 = origin
    whole = np.zeros(shape, dtype=bool)
    for r, c in region.cells:
        whole[r - r0, c - c0] = True
    if whole.any():
        base = build_tree(whole, "kruskal", seed=seed)
        cells, right, down = base.cells.copy(), base.right.copy(), base.down.copy()
    else:
        cells, right, down = whole, whole.copy(), whole.copy()
    for leaf in region.leaves:
        lr, lc = leaf.cell[0] - r0, leaf.cell[1] - c0
        cells[lr, lc] = True
        if leaf.anchor is None:
            continue
        ar, ac = leaf.anchor[0] - r0, leaf.anchor[1] - c0
        (r1, c1), (r2, _) = sorted(((lr, lc), (ar, ac)))
        if r1 == r2:
            right[r1, c1] = True
        else:
            down[r1, c1] = True
    return SpanningTree(cells=cells, right=right, down=down)


def region_path(region: Region, *, seed: int = 0) -> tuple[SubCell, ...]:
    """The robot's open walk through every sub-cell of its region, from its start."""
    corners = list(region.cells) + [leaf.cell for leaf in region.leaves]
    rows = [r for r, _ in corners]
    cols = [c for _, c in corners]
    origin = (min(rows), min(cols))
    shape = (max(rows) - origin[0] + 1, max(cols) - origin[1] + 1)
    tree = region_tree(region, origin, shape, seed)
    shift = np.array([2 * origin[0], 2 * origin[1]], dtype=np.int64)
    start = (region.start[0] - int(shift[0]), region.start[1] - int(shift[1]))
    path = stc_cycle(tree, start=start).path
    keep = expand(np.zeros(shape, dtype=bool))
    for r, c in region.cells:
        keep[2 * (r - origin[0]): 2 * (r - origin[0]) + 2,
             2 * (c - origin[1]): 2 * (c - origin[1]) + 2] = True
    for leaf in region.leaves:
        for r, c in leaf.subs:
            keep[r - shift[0], c - shift[1]] = True
    walk = path[keep[path[:, 0], path[:, 1]]]
    for candidate in (walk, np.concatenate([walk[:1], walk[1:][::-1]])):
        if _is_walk(candidate):
            return tuple((int(r), int(c)) for r, c in (candidate + shift).tolist())
    raise AssertionError(f"robot {region.robot}: its region's cycle does not open into a walk")


def _is_walk(path: IntArray) -> bool:
    return bool((np.abs(np.diff(path, axis=0)).sum(axis=1) == 1).all())
