"""Create Tree (Agmon, Hazon & Kaminka, "The Giving Tree", section 3).

Builds a spanning tree that spreads the robots evenly along its STC cycle: grow one subtree per
robot away from the others (:mod:`planner.createtree.growth`), then join the subtrees with the
best of many random bridge sets (:mod:`planner.createtree.bridges`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from planner.createtree.bridges import bridge_tries, join, search_bridges
from planner.createtree.growth import MEASURES, grow_subtrees
from planner.createtree.types import BridgeSearch, Subtrees
from planner.errors import DisconnectedRobotsError, RobotPlacementError
from planner.grid import label_components
from planner.types import BoolArray, Cell, SpanningTree, SubCell

__all__ = ["MEASURES", "BridgeSearch", "Subtrees", "create_tree", "create_tree_search"]


def _component(cells: BoolArray, starts: Sequence[Cell]) -> BoolArray:
    """The component of ``cells`` holding every start (an error if the starts are split)."""
    h, w = cells.shape
    for robot, (r, c) in enumerate(starts):
        if not (0 <= r < h and 0 <= c < w and cells[r, c]):
            raise RobotPlacementError(f"robot {robot} starts at cell ({r}, {c}), not a free cell")
    labels, _ = label_components(cells)
    found = {int(labels[cell]) for cell in starts}
    if len(found) > 1:
        raise DisconnectedRobotsError(
            f"robots start in {len(found)} disconnected parts of the map; Create Tree needs "
            "one connected work-area")
    return labels == found.pop()


def create_tree_search(cells: BoolArray, start_cells: Sequence[Cell], *,
                       measure: str = "manhattan", alpha: float = 2.0, seed: int = 0,
                       start_subcells: Sequence[SubCell] | None = None,
                       rule: str = "max") -> tuple[Subtrees, BridgeSearch]:
    """Both stages of Create Tree, with everything they tried (for tests and experiments)."""
    if not start_cells:
        raise RobotPlacementError("no robots given")
    if measure not in MEASURES:
        raise ValueError(f"unknown distance measure {measure!r}; expected one of {MEASURES}")
    area = _component(np.asarray(cells, dtype=bool), start_cells)
    rng = np.random.default_rng(seed)
    roots = list(dict.fromkeys((int(r), int(c)) for r, c in start_cells))
    sub = grow_subtrees(area, roots, measure=measure, rng=rng)
    robots = (list(start_subcells) if start_subcells is not None
              else [(2 * r, 2 * c) for r, c in start_cells])
    tries = bridge_tries(len(start_cells), int(area.sum()), alpha, rule=rule)
    return sub, search_bridges(sub, robots, tries, rng)


def create_tree(cells: BoolArray, start_cells: Sequence[Cell], *, measure: str = "manhattan",
                alpha: float = 2.0, seed: int = 0,
                start_subcells: Sequence[SubCell] | None = None,
                rule: str = "max") -> SpanningTree:
    """A spanning tree of the start cells' component that spreads the robots along its cycle.

    ``measure`` is "manhattan", "euclidean" or "path" (shortest path on the free cells);
    max{k^alpha, N} random bridge sets are tried (N = cells in the component; Alg. 1), or
    k^alpha with ``rule="power"`` (the paper's prose). Robots are
    scored at the top-left sub-cell of their start cell unless ``start_subcells`` is given.
    """
    sub, search = create_tree_search(cells, start_cells, measure=measure, alpha=alpha,
                                     seed=seed, start_subcells=start_subcells, rule=rule)
    return join(sub, search.bridges[search.best])
