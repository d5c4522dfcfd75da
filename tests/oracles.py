"""Brute-force oracles and small builders shared by tests (import as ``from oracles import ...``).

Everything here is deliberately naive: it must be obviously right, not fast.
"""

from __future__ import annotations

import itertools
import math
from collections import deque
from collections.abc import Sequence

import numpy as np

from planner.grid import label_components
from planner.types import BoolArray, RobotAllocation, SpanningTree


def gaps_of(n: int, positions: Sequence[int]) -> tuple[list[int], list[int]]:
    """Robot ids sorted along the cycle, and the gap (sub-cells strictly between) after each."""
    order = sorted(range(len(positions)), key=lambda r: positions[r])
    k = len(order)
    if k == 1:
        return order, [n - 1]
    gaps = [(positions[order[(j + 1) % k]] - positions[order[j]] - 1) % n for j in range(k)]
    return order, gaps


def walk_moves(forward: int, backward: int) -> int:
    """Moves to cover both sides of the start: out and back over one side, then the other."""
    return min(2 * forward + backward, 2 * backward + forward)


def brute_force_opt(n: int, positions: Sequence[int], speeds: Sequence[float] | None = None,
                    fuel: Sequence[int | None] | None = None) -> float:
    """Minimum over every allocation of max(moves / speed); math.inf if fuel forbids them all.

    Enumerates, for every gap, every pair (forward cover of the robot behind, backward cover
    of the robot ahead) that covers the gap without passing the other robot's start, overlaps
    included, and every combination of those pairs.
    """
    k = len(positions)
    order, gaps = gaps_of(n, positions)
    speed = [1.0 if speeds is None else float(speeds[r]) for r in order]
    limit = [None if fuel is None else fuel[r] for r in order]
    pairs = [[(a, b) for a in range(g + 1) for b in range(g + 1) if a + b >= g] for g in gaps]
    best = math.inf
    for choice in itertools.product(*pairs):
        worst = 0.0
        for j in range(k):
            forward = choice[j][0]
            backward = choice[(j - 1) % k][1]
            m = walk_moves(forward, backward)
            cap = limit[j]
            if cap is not None and m > cap:
                worst = math.inf
                break
            worst = max(worst, m / speed[j])
        best = min(best, worst)
    return best


def bfs_tree(cells: BoolArray) -> SpanningTree:
    """A BFS spanning tree of connected cells, rooted at the first cell in row-major order."""
    cells = np.asarray(cells, dtype=bool)
    h, w = cells.shape
    right = np.zeros((h, w), dtype=bool)
    down = np.zeros((h, w), dtype=bool)
    free = [(int(r), int(c)) for r, c in np.argwhere(cells)]
    if not free:
        raise ValueError("no cells to span")
    seen = {free[0]}
    queue = deque([free[0]])
    while queue:
        r, c = queue.popleft()
        for dr, dc in ((-1, 0), (0, 1), (1, 0), (0, -1)):
            nr, nc = r + dr, c + dc
            if 0 <= nr < h and 0 <= nc < w and cells[nr, nc] and (nr, nc) not in seen:
                seen.add((nr, nc))
                queue.append((nr, nc))
                if dr == 0:
                    right[r, min(c, nc)] = True
                else:
                    down[min(r, nr), c] = True
    if len(seen) != len(free):
        raise ValueError(f"cells are not connected: reached {len(seen)} of {len(free)}")
    return SpanningTree(cells=cells, right=right, down=down)


def random_cells(rng: np.random.Generator, shape: tuple[int, int],
                 obstacle_fraction: float) -> BoolArray:
    """Random free cells forming one 4-connected component (the largest one; never empty)."""
    while True:
        free = rng.random(shape) >= obstacle_fraction
        labels, count = label_components(free)
        if count:
            sizes = np.bincount(labels.ravel())[1:]
            return labels == int(np.argmax(sizes)) + 1


def cover_sets(n: int, allocations: Sequence[RobotAllocation]) -> list[set[int]]:
    """Per robot, the cycle indices its forward/backward cover claims (start included)."""
    out = []
    for a in allocations:
        own = {a.start_index}
        own.update((a.start_index + d) % n for d in range(1, a.forward + 1))
        own.update((a.start_index - d) % n for d in range(1, a.backward + 1))
        out.append(own)
    return out


def walked_indices(n: int, allocation: RobotAllocation) -> list[int]:
    """The cycle indices a robot stands on when it follows its legs one move at a time."""
    at = allocation.start_index
    out = [at]
    for leg in allocation.legs:
        for _ in range(leg.length):
            at = (at + leg.direction.sign) % n
            out.append(at)
    return out


def assert_tiles(n: int, allocations: Sequence[RobotAllocation]) -> None:
    """Every index covered by exactly one robot; each walk visits exactly its own cover."""
    counts = [0] * n
    for robot, own in enumerate(cover_sets(n, allocations)):
        walked = walked_indices(n, allocations[robot])
        assert set(walked) == own, f"robot {robot} walks {sorted(set(walked))}, owns {sorted(own)}"
        assert len(walked) - 1 == allocations[robot].steps
        assert allocations[robot].steps == walk_moves(allocations[robot].forward,
                                                       allocations[robot].backward)
        for i in own:
            counts[i] += 1
    bad = [i for i, c in enumerate(counts) if c != 1]
    assert not bad, f"indices covered other than once: {bad[:10]} (counts {counts})"
