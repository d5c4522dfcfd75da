"""Seeded instance generators shared by the papers' reproductions and the benchmarks."""

from __future__ import annotations

import numpy as np

from planner.grid import expand, label_components
from planner.types import BoolArray, SubCell


def grid_with_obstacles(rows: int, cols: int, obstacles: int,
                        rng: np.random.Generator) -> BoolArray:
    """A rows x cols cell grid with ``obstacles`` random blocked cells, kept 4-connected.

    Cells are blocked one at a time in random order, skipping any cell whose removal would
    disconnect the free cells (as the papers require a connected work-area).
    """
    cells = np.ones((rows, cols), dtype=bool)
    if obstacles <= 0:
        return cells
    placed = 0
    for flat in rng.permutation(rows * cols):
        r, c = divmod(int(flat), cols)
        cells[r, c] = False
        if label_components(cells)[1] == 1:
            placed += 1
            if placed == obstacles:
                return cells
        else:
            cells[r, c] = True
    raise ValueError(f"could not place {obstacles} obstacles on {rows} x {cols} connected")


def random_sub_cells(cells: BoolArray, k: int, rng: np.random.Generator) -> list[SubCell]:
    """``k`` distinct random sub-cells of the free cells."""
    free = np.argwhere(expand(cells))
    chosen = rng.choice(len(free), size=k, replace=False)
    return [(int(free[i][0]), int(free[i][1])) for i in chosen]


def based_sub_cells(cells: BoolArray, k: int, bases: int,
                    rng: np.random.Generator) -> list[SubCell]:
    """``k`` robots split as evenly as possible over ``bases`` random base positions.

    The robots of one base stand on the sub-cells nearest to it (breadth-first over free
    sub-cells), as robots leaving one doorway would.
    """
    fine = expand(cells)
    free = np.argwhere(fine)
    taken: set[SubCell] = set()
    out: list[SubCell] = []
    sizes = [k // bases + (1 if b < k % bases else 0) for b in range(bases)]
    for size in sizes:
        while True:
            r, c = free[int(rng.integers(len(free)))]
            base = (int(r), int(c))
            if base not in taken:
                break
        out.extend(_nearest_free(fine, base, size, taken))
    return out


def _nearest_free(fine: BoolArray, base: SubCell, size: int,
                  taken: set[SubCell]) -> list[SubCell]:
    h, w = fine.shape
    queue = [base]
    seen = {base}
    found: list[SubCell] = []
    head = 0
    while head < len(queue) and len(found) < size:
        r, c = queue[head]
        head += 1
        if (r, c) not in taken:
            taken.add((r, c))
            found.append((r, c))
        for nr, nc in ((r - 1, c), (r, c + 1), (r + 1, c), (r, c - 1)):
            if 0 <= nr < h and 0 <= nc < w and fine[nr, nc] and (nr, nc) not in seen:
                seen.add((nr, nc))
                queue.append((nr, nc))
    return found


def maze_cells(rows: int, cols: int, rng: np.random.Generator) -> BoolArray:
    """A (2 rows - 1) x (2 cols - 1) cell grid carved as a perfect maze (randomised
    depth-first search): one-cell corridors, every free cell reachable one way only."""
    cells = np.zeros((2 * rows - 1, 2 * cols - 1), dtype=bool)
    cells[0, 0] = True
    seen = {(0, 0)}
    stack = [(0, 0)]
    while stack:
        r, c = stack[-1]
        fresh = [(r + dr, c + dc) for dr, dc in ((0, 1), (1, 0), (0, -1), (-1, 0))
                 if 0 <= r + dr < rows and 0 <= c + dc < cols and (r + dr, c + dc) not in seen]
        if not fresh:
            stack.pop()
            continue
        nr, nc = fresh[int(rng.integers(len(fresh)))]
        seen.add((nr, nc))
        cells[2 * nr, 2 * nc] = cells[r + nr, c + nc] = True
        stack.append((nr, nc))
    return cells
