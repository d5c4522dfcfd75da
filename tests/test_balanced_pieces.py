"""planner.balanced.pieces against brute force: what giving each cell of a region also gives
(the cells only it links to the region's pinned cells), and the region's cut cells."""

from __future__ import annotations

import random

import numpy as np

from planner.balanced.pieces import RegionPieces
from planner.balanced.regions import _partition_state
from planner.balanced.state import articulation_points, grid_graph
from planner.grid import work_area
from planner.maps import resolve_world
from planner.placement import random_starts

H, W = 7, 8


def _piece_by_search(cells: set[int], neighbours: list[list[int]], pinned: set[int],
                     u: int) -> list[int]:
    """One search per cell, as relieve made it before: ``u`` and what is no longer reached
    from the first pinned cell once ``u`` is gone ([] if a pinned cell would go with it)."""
    roots = [v for v in cells if v in pinned]
    if not roots or u in roots:
        return []
    seen = {u, roots[0]}
    stack = [roots[0]]
    while stack:
        a = stack.pop()
        for b in neighbours[a]:
            if b in cells and b not in seen:
                seen.add(b)
                stack.append(b)
    if not all(v in seen for v in roots):
        return []
    return [u, *(v for v in cells if v not in seen)]


def _parts(cells: set[int], neighbours: list[list[int]]) -> int:
    """Connected parts of ``cells``."""
    seen: set[int] = set()
    parts = 0
    for start in cells:
        if start in seen:
            continue
        parts += 1
        seen.add(start)
        stack = [start]
        while stack:
            for b in neighbours[stack.pop()]:
                if b in cells and b not in seen:
                    seen.add(b)
                    stack.append(b)
    return parts


def _cut_by_removal(cells: set[int], neighbours: list[list[int]]) -> set[int]:
    """The cells whose removal leaves more parts (brute force)."""
    parts = _parts(cells, neighbours)
    return {u for u in cells if _parts(cells - {u}, neighbours) > parts}


def _region(rng: random.Random, free: np.ndarray, neighbours: list[list[int]],
            connected: bool) -> set[int]:
    """A random region: grown from one cell (connected), or any cells (in parts)."""
    cells_free = [u for u in range(H * W) if free[u]]
    if not connected:
        return set(rng.sample(cells_free, rng.randint(1, len(cells_free))))
    region = {rng.choice(cells_free)}
    frontier = list(region)
    size = rng.randint(1, len(cells_free))
    while frontier and len(region) < size:
        a = frontier.pop(rng.randrange(len(frontier)))
        for b in neighbours[a]:
            if free[b] and b not in region and rng.random() < 0.7:
                region.add(b)
                frontier.append(b)
    return region


def test_pieces_and_cut_cells_equal_one_search_per_cell() -> None:
    for seed in range(300):
        _check(random.Random(seed), connected=seed % 4 != 0)


def _check(rng: random.Random, connected: bool) -> None:
    grid = np.array([[rng.random() > 0.15 for _ in range(W)] for _ in range(H)])
    free, neighbours, _, _ = grid_graph(H, W, grid.tobytes())
    free_mask = np.array(free, dtype=bool)
    region = _region(rng, free_mask, neighbours, connected)
    pinned = set(rng.sample(sorted(region), rng.randint(0, min(3, len(region)))))
    pieces = RegionPieces(region, neighbours, lambda v: v in pinned)
    assert pieces.cut == articulation_points(region, neighbours) \
        == _cut_by_removal(region, neighbours)
    for u in region:
        expected = _piece_by_search(region, neighbours, pinned, u)
        assert pieces.cells(u) == expected, (u, sorted(region), sorted(pinned))
        assert pieces.size(u) == len(expected)


def test_bordering_cells_follow_every_change_of_owner() -> None:
    """PartitionState.bordering after seeding, growth, thousands of transfers and rolled-back
    chains: the cells owned and next to another region, recomputed from the labels."""
    for world, k in (("rooms:24x24:3", 7), ("obstacles:24x24:30%:4", 9), ("office", 6)):
        grid = resolve_world(world)
        area = work_area(grid, random_starts(grid, k, 1))
        state = _partition_state(area, 1, None, None)
        assert state is not None and state.transfers > 0
        label, neighbours = state.label, state.neighbours
        expected = [label[u] >= 0 and any(label[v] >= 0 and label[v] != label[u]
                                          for v in neighbours[u]) for u in range(len(label))]
        assert state.bordering == expected, world
        assert any(expected) and not all(expected)
