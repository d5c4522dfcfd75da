"""Seeded city-like maps: a street grid between blocks of buildings, yards and parks.

    city_grid(256, seed=3)      # 256 x 256 sub-cells, about 47 000 of them free

Made for planning at scale (issue 14): a large, well-connected map with long corridors
(streets), dead-end alleys and open squares, unlike the uniform random obstacles of the
benchmarks. Built on coarse cells (2 x 2 sub-cells) so no free sub-cell is lost to the
coarsening; every free cell is 4-connected to the streets.
"""

from __future__ import annotations

import numpy as np

from planner.grid import expand
from planner.types import BoolArray, OccupancyGrid

BLOCK = (8, 15)  # cells between streets (inclusive range)
STREET = (2, 4)  # street width in cells (inclusive range)
PARK = 0.12  # share of blocks left open (squares, parks)


def city_grid(size: int, seed: int) -> OccupancyGrid:
    """A ``size`` x ``size`` sub-cell city map (size even), the same for the same seed."""
    if size < 8 or size % 2:
        raise ValueError(f"a city map needs an even size of at least 8 sub-cells, got {size}")
    rng = np.random.default_rng(seed)
    cells = city_cells(size // 2, size // 2, rng)
    return OccupancyGrid(expand(cells), name=f"city-{size}-{seed}")


def city_cells(rows: int, cols: int, rng: np.random.Generator) -> BoolArray:
    """Free cells of a rows x cols city: streets, then each block built up or left open."""
    cells = np.zeros((rows, cols), dtype=bool)
    row_blocks = _blocks(rows, rng)
    col_blocks = _blocks(cols, rng)
    for r0, r1 in _streets(rows, row_blocks):
        cells[r0:r1, :] = True
    for c0, c1 in _streets(cols, col_blocks):
        cells[:, c0:c1] = True
    for r0, r1 in row_blocks:
        for c0, c1 in col_blocks:
            _build_block(cells, r0, r1, c0, c1, rng)
    return cells


def _blocks(length: int, rng: np.random.Generator) -> list[tuple[int, int]]:
    """Block spans [a, b) along one axis, separated by streets; the edges are streets."""
    spans = []
    at = int(rng.integers(STREET[0], STREET[1] + 1))
    while True:
        size = int(rng.integers(BLOCK[0], BLOCK[1] + 1))
        if at + size + STREET[0] > length:
            break
        spans.append((at, at + size))
        at += size + int(rng.integers(STREET[0], STREET[1] + 1))
    return spans


def _streets(length: int, blocks: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """The gaps between blocks (and at both edges): the streets along one axis."""
    edges = [0] + [x for span in blocks for x in span] + [length]
    return [(edges[i], edges[i + 1]) for i in range(0, len(edges), 2)]


def _build_block(cells: BoolArray, r0: int, r1: int, c0: int, c1: int,
                 rng: np.random.Generator) -> None:
    """Leave a park open, or put up to four buildings split by alleys, with a sidewalk."""
    if rng.random() < PARK:
        cells[r0:r1, c0:c1] = True
        for _ in range(int(rng.integers(0, 4))):  # a few kiosks / trees in the park
            r = int(rng.integers(r0 + 1, r1 - 1))
            c = int(rng.integers(c0 + 1, c1 - 1))
            cells[r, c] = False
        return
    # a one-cell sidewalk round the block; an alley splits it in two, maybe four
    cells[r0:r1, c0:c1] = True
    inner = np.zeros((r1 - r0, c1 - c0), dtype=bool)
    inner[1:-1, 1:-1] = True
    if rng.random() < 0.7:
        split = int(rng.integers(3, r1 - r0 - 3))
        inner[split, :] = False
    if rng.random() < 0.5:
        split = int(rng.integers(3, c1 - c0 - 3))
        inner[:, split] = False
    if rng.random() < 0.35:  # a courtyard, reached through a gate in the building's wall
        h, w = r1 - r0, c1 - c0
        inner[h // 2 - 1: h // 2 + 1, w // 2 - 1: w // 2 + 1] = False
        inner[h // 2 - 1, 1: w // 2 - 1] = False
    cells[r0:r1, c0:c1] &= ~inner
