"""The connection table of Alg. 2 (connection[j][0..1]), generalised to every border edge.

A connection is an edge (my cell, their cell) between my tree and a cell another robot holds
or claimed. The paper keeps the first and last per robot; we keep all of them (a dead body
can split a dead robot's tree) and still expose the first and last.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from planner.ormstc.knowledge import Knowledge
from planner.ormstc.types import Cell

Link = tuple[Cell, Cell]


@dataclass
class Connections:
    links: dict[Link, int] = field(default_factory=dict)  # link -> robot believed to hold it
    first: dict[int, Link] = field(default_factory=dict)  # connection[j][0]
    last: dict[int, Link] = field(default_factory=dict)  # connection[j][1]
    # links whose holder only claimed the cell: if no edge is heard by then, retry it
    unsure: dict[Link, float] = field(default_factory=dict)

    def record(self, holder: int, link: Link, retry_at: float | None = None) -> None:
        self.links[link] = holder
        if retry_at is not None:
            self.unsure[link] = retry_at
        self.first.setdefault(holder, link)
        self.last[holder] = link

    def drop(self, link: Link) -> None:
        self.links.pop(link, None)
        self.unsure.pop(link, None)

    def holders(self) -> set[int]:
        return set(self.links.values())

    def targets(self, know: Knowledge, mine: set[Cell], now: float,
                over: bool) -> tuple[list[Link], float]:
        """Links into cells no live robot holds (line 26), and when to look again.

        Cells of dead robots count only while the mission is not over (line 25); a cell lost
        to a claimant that never built its edge is retried in any case.
        """
        out: list[Link] = []
        retry_at = math.inf
        for link, holder in list(self.links.items()):
            theirs = link[1]
            if theirs in mine or theirs in know.obstacle:
                self.drop(link)
                continue
            owner = know.live_owner(theirs)
            if owner is not None:
                self.links[link] = owner
                self.unsure.pop(link, None)
                continue
            expiry = self.unsure.get(link, math.inf)
            if expiry <= now or (holder in know.dead and not over):
                out.append(link)
            else:
                retry_at = min(retry_at, expiry)
        return out, retry_at
