"""ORMSTC claims, tree edges and the conflicts between them, as seen on the wire.

Read by field name (``robot``, ``cell``, ``parent``, ``child``, as in planner.ormstc.types),
so that the monitor follows ORMSTC messages whether or not this process has their bus types:
a claim says "robot r wants cell c", a tree edge "parent -> child, child is mine now", a
retraction "no edge into child after all: it is blocked". Two robots claiming one cell is a
conflict; the tree edge that follows names the winner.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from deploy.monitor.types import EventKind
from planner.types import Cell


@dataclass(frozen=True)
class ClaimEvent:
    kind: EventKind
    robot: int | None
    text: str = ""
    edge: tuple[Cell, Cell] | None = None


@dataclass(frozen=True)
class Conflict:
    """Robots that claimed ``cell`` before it was settled, and who got it (None: not yet)."""

    cell: Cell
    claimants: tuple[int, ...]
    winner: int | None
    t: float


@dataclass
class ClaimBook:
    """Open claims per cell, owners of cells, and settled conflicts."""

    open: dict[Cell, dict[int, float]] = field(default_factory=dict)
    owner: dict[Cell, int] = field(default_factory=dict)
    conflicts: list[Conflict] = field(default_factory=list)
    claims: int = 0

    def apply(self, t: float, kind: str, fields: Mapping[str, Any]) -> list[ClaimEvent]:
        robot = fields.get("robot")
        if isinstance(robot, bool) or not isinstance(robot, int):
            return []
        if kind == "ormstc/claim":
            cell = _cell(fields.get("cell"))
            return [] if cell is None else self._claim(t, robot, cell)
        if kind == "ormstc/tree":
            parent, child = _cell(fields.get("parent")), _cell(fields.get("child"))
            return [] if parent is None or child is None else \
                self._edge(t, robot, parent, child)
        if kind == "ormstc/retract":
            parent, child = _cell(fields.get("parent")), _cell(fields.get("child"))
            return [] if parent is None or child is None else \
                self._retraction(robot, parent, child)
        if kind == "ormstc/done":
            return [ClaimEvent("completed", robot,
                               f"robot {robot} completed ({fields.get('cells')} cells)")]
        if kind == "ormstc/withdraw":
            return [ClaimEvent("withdrawn", robot, f"robot {robot} withdrew its completion "
                                                   f"for robot {fields.get('peer')}'s cells")]
        if kind == "ormstc/dead":
            dead = fields.get("dead")
            if isinstance(dead, int):
                self.open = {c: {r: w for r, w in who.items() if r != dead}
                             for c, who in self.open.items()}
                self.owner = {c: r for c, r in self.owner.items() if r != dead}
        return []

    def _claim(self, t: float, robot: int, cell: Cell) -> list[ClaimEvent]:
        self.claims += 1
        owner = self.owner.get(cell)
        if owner is not None:
            # Settled before it was made (the claimant had not heard the edge yet): an open
            # claim here would differ from what a late joiner learns from state replies.
            return [ClaimEvent("claimed", robot, f"robot {robot} claims cell {cell} "
                                                 f"(already robot {owner}'s)")]
        claimants = self.open.setdefault(cell, {})
        rivals = sorted(set(claimants) - {robot})
        claimants.setdefault(robot, t)
        text = f"robot {robot} claims cell {cell}"
        if rivals:
            text += f" (conflict with robot{'s' if len(rivals) > 1 else ''} " \
                    f"{', '.join(map(str, rivals))})"
        return [ClaimEvent("claimed", robot, text)]

    def _edge(self, t: float, robot: int, parent: Cell, child: Cell) -> list[ClaimEvent]:
        self.owner[child] = robot
        events = [ClaimEvent("tree_edge", robot, edge=(min(parent, child), max(parent, child)))]
        claimants = self.open.pop(child, {})
        if len(set(claimants) | {robot}) > 1:
            self.conflicts.append(Conflict(child, tuple(sorted(claimants)), robot, t))
            events += [ClaimEvent("conflict_lost", loser,
                                  f"robot {loser} lost cell {child} to robot {robot}")
                       for loser in sorted(set(claimants) - {robot})]
        return events

    def _retraction(self, robot: int, parent: Cell, child: Cell) -> list[ClaimEvent]:
        if self.owner.get(child) == robot:
            del self.owner[child]
        return [ClaimEvent("tree_edge_retracted", robot,
                           f"robot {robot} gave cell {child} up from inside (an obstacle or a "
                           "dead robot's body in it): no tree edge into it",
                           edge=(min(parent, child), max(parent, child)))]

    def restore(self, t: float, robot: int, tree: Iterable[tuple[Cell, Cell]],
                claims: Iterable[Cell]) -> list[ClaimEvent]:
        """A robot's state reply: its tree edges and unsettled claims, for a late joiner.
        Idempotent; a claim on a cell someone owns is already settled (conflicts that were
        settled before this monitor joined stay unknown)."""
        events = []
        for parent, child in tree:
            self.owner[child] = robot
            self.open.pop(child, None)
            events.append(ClaimEvent("tree_edge", robot, edge=(min(parent, child),
                                                               max(parent, child))))
        for cell in claims:
            if cell not in self.owner:
                self.open.setdefault(cell, {}).setdefault(robot, t)
        return events

    def unsettled(self) -> list[Conflict]:
        """Cells two or more robots claim that nobody has built a tree edge into yet."""
        return [Conflict(cell, tuple(sorted(c)), None, min(c.values()))
                for cell, c in sorted(self.open.items()) if len(c) > 1]


def _cell(value: Any) -> Cell | None:
    if isinstance(value, (tuple, list)) and len(value) == 2 \
            and all(isinstance(v, int) and not isinstance(v, bool) for v in value):
        return (int(value[0]), int(value[1]))
    return None


def fields_of(msg: Any) -> dict[str, Any]:
    """The fields of a message dataclass as a mapping (empty for anything else)."""
    if dataclasses.is_dataclass(msg) and not isinstance(msg, type):
        return {f.name: getattr(msg, f.name) for f in dataclasses.fields(msg)}
    return {}
