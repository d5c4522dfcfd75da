"""Value types of Create Tree: the grown subtrees and the outcome of the bridge search."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.types import BoolArray, Cell, IntArray


@dataclass(frozen=True, eq=False)
class Subtrees:
    """The k disjoint subtrees of stage one (one per distinct robot start cell).

    ``owner[r, c]`` is the subtree id of cell (r, c) (-1 outside the work-area); ``right`` and
    ``down`` hold the subtrees' own edges, in the layout of :class:`planner.types.SpanningTree`.
    ``roots[i]`` is the start cell subtree ``i`` grew from.
    """

    owner: IntArray
    right: BoolArray
    down: BoolArray
    roots: tuple[Cell, ...]

    def __post_init__(self) -> None:
        for name in ("owner", "right", "down"):
            array = np.ascontiguousarray(getattr(self, name))
            array.setflags(write=False)
            object.__setattr__(self, name, array)

    @property
    def k(self) -> int:
        return len(self.roots)


@dataclass(frozen=True, eq=False)
class BridgeSearch:
    """Every bridge set tried and its score (largest cycle gap between consecutive robots).

    ``bridges`` is an array (tries, k - 1, 4) of edges (r1, c1, r2, c2), the second cell right
    of or below the first; ``best`` indexes the winning try.
    """

    bridges: IntArray
    scores: IntArray
    best: int
