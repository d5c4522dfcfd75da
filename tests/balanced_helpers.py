"""Shared strategies and checkers of the balanced planner tests."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from hypothesis import strategies as st

from planner.balanced import Partition, balanced_plan, partition
from planner.balanced.plan import FALLBACK, WALK_OUT
from planner.geometry import sub_cells_of
from planner.grid import expand, label_components, work_area
from planner.invariants import check_plan
from planner.placement import random_starts
from planner.types import OccupancyGrid, SubCell


def relaxed(plan_notes: Sequence[str]) -> bool:
    """Plans that promise coverage but not one visit per sub-cell (see planner.balanced.plan)."""
    return any(note.startswith((FALLBACK, WALK_OUT)) for note in plan_notes)


def grid_of(rows: Sequence[str]) -> OccupancyGrid:
    """Coarse-cell picture ('#' blocked) as a sub-cell grid."""
    coarse = np.array([[ch != "#" for ch in row] for row in rows], dtype=bool)
    return OccupancyGrid(expand(coarse))


@st.composite
def instances(draw: st.DrawFn, max_side: int = 7, max_k: int = 8
              ) -> tuple[OccupancyGrid, tuple[SubCell, ...], int]:
    """A random coarse map, k random distinct starts in its largest component, a seed."""
    h = draw(st.integers(1, max_side))
    w = draw(st.integers(1, max_side))
    seed = draw(st.integers(0, 10_000))
    rng = np.random.default_rng(seed)
    density = draw(st.sampled_from([0.0, 0.1, 0.25, 0.4]))
    coarse = rng.random((h, w)) >= density
    if not coarse.any():
        coarse[0, 0] = True
    grid = OccupancyGrid(expand(coarse))
    labels, _ = label_components(coarse)
    biggest = int(np.bincount(labels.ravel())[1:].max())
    k = draw(st.integers(1, min(max_k, 4 * biggest)))
    return grid, random_starts(grid, k, seed), seed


@st.composite
def crowded(draw: st.DrawFn) -> tuple[OccupancyGrid, tuple[SubCell, ...], int]:
    """Small maps where several robots start in the same cell (2 to 4 per cell)."""
    grid, starts, seed = draw(instances(max_side=5, max_k=4))
    area = work_area(grid, starts)
    cells = np.argwhere(area.cells)
    rng = np.random.default_rng(seed)
    extra: list[SubCell] = []
    for _ in range(draw(st.integers(1, 3))):
        r, c = cells[rng.integers(len(cells))]
        subs = list(sub_cells_of((int(r), int(c))))
        count = int(rng.integers(2, 5))
        extra.extend(subs[i] for i in rng.choice(4, size=count, replace=False))
    merged = tuple(dict.fromkeys([*starts, *extra]))
    return grid, merged, seed


def check_regions(parts: Partition, area_cells: np.ndarray, starts: Sequence[SubCell]) -> None:
    """Regions tile the area's sub-cells; whole cells connected; leaves hang off own cells."""
    owner = np.full(expand(area_cells).shape, -1)
    for region in parts.regions:
        assert region.start == starts[region.robot]
        subs = [s for cell in region.cells for s in sub_cells_of(cell)]
        subs += [s for leaf in region.leaves for s in leaf.subs]
        for s in subs:
            assert owner[s] == -1, f"sub-cell {s} in two regions"
            owner[s] = region.robot
        assert region.start in subs
        if region.cells:
            mask = np.zeros(area_cells.shape, dtype=bool)
            mask[tuple(np.array(region.cells).T)] = True
            assert label_components(mask)[1] == 1, f"robot {region.robot}: split region"
        for leaf in region.leaves:
            assert set(leaf.subs) <= set(sub_cells_of(leaf.cell))
            if leaf.anchor is not None:
                assert leaf.anchor in region.cells
                assert abs(leaf.anchor[0] - leaf.cell[0]) + abs(leaf.anchor[1] - leaf.cell[1]) == 1
            else:
                assert not region.cells
    assert ((owner >= 0) == expand(area_cells)).all()


def check_balanced(grid: OccupancyGrid, starts: tuple[SubCell, ...], seed: int) -> None:
    area = work_area(grid, starts)
    plan = balanced_plan(area, seed=seed)
    assert plan.algo == "balanced"
    assert plan.k == len(starts)
    assert plan.makespan >= math.ceil(area.n / len(starts)) - 1
    if any(note.startswith(FALLBACK) for note in plan.notes):
        check_plan(plan, area, max_visits=2)  # optimal MSTC: sub-cells at most twice
        return
    parts = partition(area, seed=seed)  # the regions grown from the starts, no walks
    if parts is None:  # shared start cells wall part of the map off: regions grown elsewhere
        assert relaxed(plan.notes)
        check_plan(plan, area, max_visits=len(starts) + 1, own_revisits_only=False)
        return
    check_regions(parts, area.cells, starts)
    assert sum(parts.sizes) == area.n
    if relaxed(plan.notes):
        check_plan(plan, area, max_visits=len(starts) + 1, own_revisits_only=False)
        assert plan.makespan < max(parts.sizes) - 1  # walks are taken only when they pay
        return
    check_plan(plan, area)  # every sub-cell exactly once, by one robot, 4-adjacent moves
    assert [rp.steps for rp in plan.robots] == [size - 1 for size in parts.sizes]
    assert sum(rp.steps + 1 for rp in plan.robots) == area.n


def grid_distances(free: np.ndarray, sources: Sequence[tuple[int, int]]
                   ) -> dict[tuple[int, int], int]:
    """Oracle: breadth-first distances over a grid's free cells (or sub-cells) from the
    nearest source."""
    h, w = free.shape
    dist = dict.fromkeys(sources, 0)
    frontier = list(sources)
    while frontier:
        nxt = []
        for r, c in frontier:
            for cell in ((r - 1, c), (r + 1, c), (r, c - 1), (r, c + 1)):
                if 0 <= cell[0] < h and 0 <= cell[1] < w and free[cell] and cell not in dist:
                    dist[cell] = dist[(r, c)] + 1
                    nxt.append(cell)
        frontier = nxt
    return dist
