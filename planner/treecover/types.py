"""Frozen value types of connected tree coverage: trees, split heights, moves, results."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum

import numpy as np


@dataclass(frozen=True, eq=False)
class Tree:
    """A rooted tree with nodes numbered so that every parent precedes its children.

    Node 0 is the root. ``parent[0] == -1``. The children of ``v`` are
    ``child_index[child_start[v]:child_start[v + 1]]`` in their stored order. Heights follow
    the paper: the deepest leaves are at height 0 and the root at height ``height``, so a node's
    height is ``height - depth[v]`` (a level, the same for all nodes at one depth).
    """

    parent: np.ndarray
    depth: np.ndarray
    child_start: np.ndarray
    child_index: np.ndarray
    labels: tuple[str, ...] = ()
    name: str = "tree"
    branching: int = field(default=0)

    @property
    def n(self) -> int:
        return int(self.parent.shape[0])

    @property
    def height(self) -> int:
        return int(self.depth.max())

    def children(self, v: int) -> np.ndarray:
        return self.child_index[self.child_start[v]:self.child_start[v + 1]]

    def level(self, v: int) -> int:
        """The paper's height h(v) of node ``v``."""
        return self.height - int(self.depth[v])

    def label(self, v: int) -> str:
        return self.labels[v] if self.labels else str(v)


@dataclass(frozen=True)
class Splits:
    """Split heights h_1 > ... > h_m at which NCOCTA / COCTA leave a robot and divide the rest.

    An empty ``heights`` means no split: the whole team walks one depth-first search together.
    """

    heights: tuple[int, ...]

    def __post_init__(self) -> None:
        if any(a <= b for a, b in zip(self.heights, self.heights[1:], strict=False)):
            raise ValueError(f"split heights must strictly decrease: {self.heights}")
        if any(h < 1 for h in self.heights):
            raise ValueError(f"split heights must be >= 1: {self.heights}")

    @property
    def m(self) -> int:
        return len(self.heights)

    @property
    def h1(self) -> int:
        """Highest split height; -1 without splits (every node is then above h_1)."""
        return self.heights[0] if self.heights else -1

    @property
    def hm(self) -> int:
        return self.heights[-1] if self.heights else 0


class Algo(Enum):
    NCOCTA = "ncocta"
    COCTA = "cocta"


@dataclass(frozen=True, slots=True)
class Move:
    """``count`` robots walk the edge between ``src`` and ``dst`` in one time step."""

    src: int
    dst: int
    count: int


@dataclass(frozen=True, eq=False)
class CoverageResult:
    """Outcome of one synchronous coverage run.

    ``time`` counts steps until the root is finished (every node visited and every robot back
    at the root), the same convention as the single-robot time ``2 (|V| - 1)`` (a depth-first
    search that returns to the root), so ``speedup = single_time / time``.
    """

    algo: Algo
    robots: int
    splits: Splits
    time: int
    explore_time: int
    single_time: int
    connected: bool
    visit_time: np.ndarray
    occupied: tuple[int, ...]

    @property
    def speedup(self) -> float:
        return self.single_time / self.time if self.time else 1.0
