"""The map as the wire draws it: coverage, the spanning-tree edges between cells and the
offline plan's tree. Pure; owned and fed by the fleet model, which reads robots and records.

Tree edges come from three sources of different weight: ORMSTC's own tree messages (built,
never overridden), simhw's first crossers of each border (the truth about walks) and the
order CoverEvents arrived in (a guess a later WorldState answer corrects).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from bus.messages import NO_ROBOT, WorldState, world_crossed, world_first
from deploy.monitor.coverage import CoverageMap
from deploy.monitor.planned import Edge, planned_edges
from deploy.monitor.robots import RobotView
from planner.errors import PlannerError
from planner.types import SubCell


class WorldPicture:
    """Coverage plus the tree edges drawn on the map, and the offline plan's tree."""

    def __init__(self, invalid: Counter[str]) -> None:
        self.cover = CoverageMap()
        # Tree edges drawn: ORMSTC's own (built) win over those seen crossed by a walk.
        self.edges: dict[Edge, int] = {}
        self._built: set[Edge] = set()
        # ORMSTC edges taken back (a cell given up from inside): the robot did cross that
        # border, into the cell and back, but no tree edge runs there
        self._retracted: set[Edge] = set()
        self._planned: tuple[Any, frozenset[Edge] | None] = (None, None)
        self._firsts_seen: tuple[npt.NDArray[np.uint8], ...] | None = None
        self._invalid = invalid  # the fleet model's counter of messages that make no sense

    def crossing(self, a: SubCell, b: SubCell, robot: int) -> None:
        """A move between two cells runs along a spanning-tree edge (STC never crosses a
        cell border elsewhere), so the robots' walks show their trees."""
        ca, cb = (a[0] // 2, a[1] // 2), (b[0] // 2, b[1] // 2)
        edge = (min(ca, cb), max(ca, cb))
        if ca != cb and abs(ca[0] - cb[0]) + abs(ca[1] - cb[1]) == 1 \
                and edge not in self._retracted:
            self.edges.setdefault(edge, robot)

    def crossed(self, edge: Edge, robot: int) -> None:
        """simhw's first crosser of a border: the truth, so it replaces the guess made from
        the order CoverEvents of different robots arrived in (not an edge ORMSTC built)."""
        if edge not in self._built and edge not in self._retracted:
            self.edges[edge] = robot

    def built_edge(self, edge: Edge, robot: int) -> None:
        self._built.add(edge)
        self._retracted.discard(edge)
        self.edges[edge] = robot

    def retracted_edge(self, edge: Edge) -> None:
        """An ORMSTC edge its robot took back: not drawn, whoever crossed the border."""
        self._built.discard(edge)
        self._retracted.add(edge)
        self.edges.pop(edge, None)

    def merge_firsts(self, state: WorldState) -> None:
        """First visitors and first crossers: what a late joiner never saw happen. Only
        entries that changed since the last answer are merged (they never change once set),
        so a periodic answer costs time in proportion to what happened meanwhile."""
        try:
            arrays = (world_first(state), *world_crossed(state))
        except ValueError:
            self._invalid["world.packing"] += 1
            return
        last = self._firsts_seen
        fresh = [a != NO_ROBOT if b is None or b.shape != a.shape else (a != b) & (a != NO_ROBOT)
                 for a, b in zip(arrays, last or (None, None, None), strict=True)]
        self._firsts_seen = arrays
        first, right, down = arrays
        for r, c in np.argwhere(fresh[0]):
            self.cover.owner.setdefault((int(r), int(c)), int(first[r, c]))
        for r, c in np.argwhere(fresh[1]):
            self.crossed(((int(r), int(c)), (int(r), int(c) + 1)), int(right[r, c]))
        for r, c in np.argwhere(fresh[2]):
            self.crossed(((int(r), int(c)), (int(r) + 1, int(c))), int(down[r, c]))

    def planned_tree(self, robots: Mapping[int, RobotView]) -> frozenset[Edge] | None:
        """The offline plan's tree edges, once the map, every robot's start (ids 0..k-1)
        and one agreed tree kind and seed are known; None before, or if they make no plan."""
        views = [robots.get(r) for r in range(len(robots))]
        if self.cover.free is None or any(v is None or v.start is None or not v.tree_kind
                                          for v in views):
            return None
        inputs = (self.cover.free.shape, tuple((v.start, v.tree_kind, v.seed)
                                               for v in views if v is not None))
        if len({(kind, seed) for _, kind, seed in inputs[1]}) != 1:
            return None
        if self._planned[0] != inputs:
            starts = [start for start, _, _ in inputs[1] if start is not None]
            _, kind, seed = inputs[1][0]
            try:
                edges: frozenset[Edge] | None = planned_edges(self.cover.free, starts, kind,
                                                              seed)
            except PlannerError:
                self._invalid["plan.unbuildable"] += 1
                edges = None
            self._planned = (inputs, edges)
        return self._planned[1]
