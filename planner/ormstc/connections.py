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
    # the last scan's inputs and answer: watchers rescan on every wake, mostly for nothing
    _inputs: tuple[int, int, int, bool] | None = field(default=None, repr=False)
    _answer: tuple[list[Link], float] = field(default_factory=lambda: ([], math.inf),
                                              repr=False)

    def record(self, holder: int, link: Link, retry_at: float | None = None) -> None:
        self._inputs = None
        self.links[link] = holder
        if retry_at is not None:
            self.unsure[link] = retry_at
        self.first.setdefault(holder, link)
        self.last[holder] = link

    def drop(self, link: Link) -> None:
        self._inputs = None
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
        # the scan reads links, unsure, mine, obstacles, the dead, owners of the far cells,
        # ``over`` and ``now`` against the expiries; the sets only grow, so their sizes are
        # versions, and ``now`` matters only once it reaches the earliest expiry
        inputs = (len(mine), len(know.obstacle), len(know.dead), over)
        if inputs == self._inputs and not know.watched_changed and now < self._answer[1]:
            return list(self._answer[0]), self._answer[1]
        know.watched.update(link[1] for link in self.links)
        know.watched_changed = False
        out: list[Link] = []
        retry_at = math.inf
        links, unsure = self.links, self.unsure
        owners, dead, obstacle = know.owners, know.dead, know.obstacle
        gone: list[Link] = []
        for link, holder in links.items():
            theirs = link[1]
            if theirs in mine or theirs in obstacle:
                gone.append(link)
                continue
            owner = None  # know.live_owner(theirs), inlined: this loop runs on every wake
            for robot in reversed(owners.get(theirs, ())):
                if robot not in dead:
                    owner = robot
                    break
            if owner is not None:
                if owner != holder:
                    links[link] = owner
                unsure.pop(link, None)
                continue
            expiry = unsure.get(link, math.inf)
            if expiry <= now or (holder in dead and not over):
                out.append(link)
            elif expiry < retry_at:
                retry_at = expiry
        for link in gone:
            self.drop(link)
        self._inputs = inputs
        self._answer = (out, retry_at)
        return list(out), retry_at
