"""Where the other robots' bodies stand and where they go next, as one offline agent knows
it: the knowledge planner.offline.traffic decides from (``--recovery rebalance``).

Nothing here is an oracle: a robot's place is the sub-cell of its latest Progress message
(its start before any), its route is its walk of the agreed plan, replaced by its route of
each re-plan (every survivor computes everyone's), and how far along that route it is is
found by matching its Progress sub-cells against the route. A robot whose last sub-cell is
off its route stepped aside: it is taken to be on its way back to where it left the route.
Robots known dead are left out (simhw's body vanishes on the death notice).

A Progress can be lost (message faults), and a robot that then stops moving would stay where
it was before in the others' knowledge for good. Two more sources put it right: the pose of
its heartbeats (every 0.2 s; taken when its simulated time is not older than the place
known), and this robot's bumps (the sub-cell bumped into is held: a body not known there is
placed there), and a re-plan places each survivor where its report said it stood. A place
found within the next 2 x LOOK places of its route advances it there; one next to where it
left its route is a step aside; any other place on the rest of its route (more than 2 x
LOOK messages lost in a row) advances it to that place's next visit.
"""

from __future__ import annotations

import contextlib
import math
from collections import deque
from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass, field

from planner.offline.traffic import LOOK, Peer, neighbours
from planner.types import Cycle, Plan

# How many of a robot's latest places are kept (see _Walk.trail).
TRAIL = 4 * LOOK


@dataclass
class _Walk:
    position: int
    base: int  # where the route starts (the route's first place is next to it)
    route: tuple[int, ...]
    done: int = 0  # places of the route walked
    seq: int = -1  # the latest Progress seq applied
    seen: float = -math.inf  # the simulated time of the latest place applied
    # the latest places heard of with their simulated times, newest last: how far along its
    # new route a robot got before this robot applied the re-plan (on_replan)
    trail: deque[tuple[int, float]] = field(default_factory=lambda: deque(maxlen=TRAIL))


@dataclass
class Bodies:
    """The other robots of ``plan`` as robot ``robot`` knows them."""

    cycle: Cycle
    robot: int
    walks: dict[int, _Walk] = field(default_factory=dict)

    @classmethod
    def of_plan(cls, plan: Plan, robot: int) -> Bodies:
        cycle = plan.cycle
        out = cls(cycle, robot)
        for rp in plan.robots:
            if rp.robot != robot:
                start = cycle.position(rp.path[0])
                out.walks[rp.robot] = _Walk(start, start, tuple(cycle.position(s)
                                                                for s in rp.path[1:]))
        return out

    def on_progress(self, robot: int, seq: int, index: int,
                    sim_time: float = -math.inf) -> bool:
        """Robot ``robot`` reported its ``seq``-th move, into cycle index ``index`` (at
        simulated time ``sim_time``); True when that is news."""
        walk = self.walks.get(robot)
        if walk is None or seq <= walk.seq or index < 0:
            return False
        walk.seq = seq
        return self._place(walk, index, sim_time)

    def on_pose(self, robot: int, index: int, sim_time: float) -> bool:
        """Robot ``robot``'s heartbeat: its body stood on cycle index ``index`` at simulated
        time ``sim_time``. True when that is news (a place its lost Progress did not tell)."""
        walk = self.walks.get(robot)
        if walk is None or index < 0:
            return False
        if index == walk.position:
            walk.seen = max(walk.seen, sim_time)
            return False
        return self._place(walk, index, sim_time)

    def _place(self, walk: _Walk, index: int, sim_time: float) -> bool:
        if sim_time < walk.seen:
            return False  # older than the place known (a delayed message)
        walk.seen = sim_time
        walk.position = index
        walk.trail.append((index, sim_time))
        window = walk.route[walk.done:walk.done + 2 * LOOK]
        if index in window:
            walk.done += window.index(index) + 1
            return True
        left_at = walk.route[walk.done - 1] if walk.done else walk.base
        if index == left_at or index in neighbours(self.cycle, left_at):
            return True  # a step aside (or back): it returns to where it left its route
        # Farther on than the window: more Progress messages than it holds were lost in a
        # row, and a heartbeat (or the next Progress that got through) tells where the body
        # is now. Read it as progress to that place's next visit on the route; a place off
        # the route leaves its next places unknown (peers() says so).
        with contextlib.suppress(ValueError):  # not on the rest of its route
            walk.done = walk.route.index(index, walk.done) + 1
        return True

    def on_bump(self, index: int, dead: Collection[int]) -> bool:
        """This robot bumped into cycle index ``index``: some body holds it. When none is
        known there, the one that most likely walked there unheard of (its Progress lost,
        or still on its way) is placed there: the one with ``index`` soonest among its next
        places, else one standing next to it (a step aside). True when that is news.

        Without this a lost Progress left a body where it was before: two robots that met
        head-on each thought the other's sub-cell free and bumped into it again and again,
        or one waited for the other to open a ring the other did not see."""
        live = [walk for robot, walk in sorted(self.walks.items()) if robot not in dead]
        if any(walk.position == index for walk in live):
            return False
        best: tuple[int, _Walk] | None = None  # (places before it on the route, walk)
        for walk in live:
            window = walk.route[walk.done:walk.done + 2 * LOOK]
            if index in window:
                rank = window.index(index)
            elif index in neighbours(self.cycle, walk.position):
                rank = 2 * LOOK  # off its route: a step aside
            else:
                continue
            if best is None or rank < best[0]:
                best = (rank, walk)
        if best is None:
            return False  # a body nobody knows of: the bump patience decides
        rank, walk = best
        if rank < 2 * LOOK:
            walk.done += rank + 1
        walk.position = index
        walk.trail.append((index, walk.seen))  # when it got there is not known: not later
        return True

    def on_replan(self, routes: Mapping[int, Sequence[int]],
                  reports: Mapping[int, tuple[int, float]]) -> None:
        """A re-plan: each survivor walks ``routes[r]`` from where its report said it stood,
        ``reports[r]`` = (place, simulated time then). Places heard of since that time
        were walked after the report: a survivor that applied the same re-plan earlier
        walked on while this robot's was computed (chaos seed 61, trials 465 and 483). It is
        placed where it was heard of last, along its new route as far as its latest place
        there (however far: only the next 2 x LOOK places were searched once, which lost it);
        a place heard of after that one is a step aside, from which it is expected back
        there. With no place heard of since its report it stands where it reported (a
        Progress lost before it stopped to report left it behind).

        Put back where it reported when its latest place was off its new route, a survivor
        that had stepped aside after walking on was later placed by its heartbeat off its
        route, its next places unknown (a robot meeting it there waited for good for a
        robot waiting on it: the likely cause of a CI rehearsal's stall, 2026-12-05)."""
        for robot, route in routes.items():
            walk = self.walks.get(robot)
            if walk is None:
                continue
            base, stopped = reports.get(robot, (walk.position, walk.seen))
            walk.base, walk.route, walk.done = base, tuple(route), 0
            since = [place for place, at in walk.trail if at > stopped]
            if not since:
                walk.position = base
                walk.trail.clear()
                continue
            walk.position = since[-1]
            for place in reversed(since):
                with contextlib.suppress(ValueError):
                    walk.done = walk.route.index(place) + 1
                    break

    def peers(self, dead: Collection[int]) -> list[Peer]:
        """Every body not known dead, with its next places as far as known."""
        out = []
        for robot, walk in sorted(self.walks.items()):
            if robot in dead:
                continue
            ahead = walk.route[walk.done:walk.done + LOOK]
            left_at = walk.route[walk.done - 1] if walk.done else walk.base
            if not ahead or walk.position == left_at \
                    or ahead[0] in neighbours(self.cycle, walk.position):
                out.append(Peer(robot, walk.position, ahead))
            elif left_at in neighbours(self.cycle, walk.position):
                out.append(Peer(robot, walk.position, (left_at, *ahead)[:LOOK], True))
            else:  # somewhere aside: its next places are unknown
                out.append(Peer(robot, walk.position, lost=True))
        return out
