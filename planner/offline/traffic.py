"""Deconfliction of walks that cross other robots (issue 14, item 6): who waits, who steps
aside, so that two bodies never meet in one sub-cell and robots that meet head-on, or a
robot parked on another's route, never block each other for good.

The rule is the world's (simhw): a body may only enter a sub-cell no body holds, not even
one that is just leaving it. Each robot decides every step from what it knows of the others
(:class:`Peer`: where each body stands and the next sub-cells it is to walk, as far as known)
and its plan's next sub-cell:

- the sub-cell is free: go (two robots racing for one: the world lets the first in, the
  other bumps and decides again);
- a body stands there: wait, except when the robots wait on each other in a ring (two
  meeting head-on, or longer rings): then the highest robot id of the ring that has a free
  neighbouring sub-cell steps aside into it, preferring one off the others' next sub-cells,
  and later walks back the way it came before it goes on with its plan;
- a robot with nothing to walk (parked, finished, waiting) that stands on another robot's
  next sub-cell steps aside the same way (it walks back only if it gets a route again).

The ring (and with it who steps aside) is computed from the same knowledge by every robot
in it, so exactly one of them moves; every step aside opens the ring. The lockstep
simulator (planner.offline.lockstep) feeds each robot's Traffic perfect knowledge, the
offline agent (agent/offline/) what Progress messages and its re-plans told it: the same
code decides in both. Counts (waits, detours, bumps) are kept per robot.

Places are cycle indices of ``cycle`` (the offline machines' key space).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass, field

from planner.types import Cycle

# How many of a peer's next sub-cells a step aside tries to keep off.
LOOK = 4


@dataclass(frozen=True)
class Peer:
    """Another robot's body as known: where it stands and the sub-cells it is next to walk
    (empty when it is parked or its route is unknown)."""

    robot: int
    position: int
    ahead: tuple[int, ...] = ()
    returning: bool = False  # its next place is on its way back to its plan
    # its next places are not known (a fleet robot's knowledge, agent.offline.bodies): it
    # may be waiting on this robot, which it cannot be when it is known to be parked
    lost: bool = False


@dataclass(frozen=True)
class Go:
    """Step into ``target``; ``on_plan`` when it is the plan's next move (else a detour)."""

    target: int
    on_plan: bool


@dataclass(frozen=True)
class Hold:
    """Stay this step; ``blocker`` is the robot standing in the way (None: nothing to do)."""

    blocker: int | None = None


Step = Go | Hold


@dataclass
class TrafficCounts:
    """Per robot: waits (times it had to stop for a body in its way), detours (moves not on
    its plan: steps aside and back), bumps (moves the world refused)."""

    waits: int = 0
    detours: int = 0
    bumps: int = 0

    def as_dict(self) -> dict[str, int]:
        return {"waits": self.waits, "detours": self.detours, "bumps": self.bumps}

    def describe(self) -> str:
        """The counts as the offline agent's "completed" event states them (:func:`parse`)."""
        return f"{self.waits} waits, {self.detours} detours, {self.bumps} bumps"

    @staticmethod
    def parse(text: str) -> TrafficCounts | None:
        """The counts :meth:`describe` wrote somewhere in ``text``; None when absent."""
        found = _COUNTS.search(text)
        if found is None:
            return None
        return TrafficCounts(*(int(g) for g in found.groups()))


_COUNTS = re.compile(r"(\d+) waits, (\d+) detours, (\d+) bumps")


def neighbours(cycle: Cycle, index: int) -> list[int]:
    """The cycle indices 4-adjacent to ``index`` (up, right, down, left)."""
    r, c = cycle.at(index)
    out = []
    for sub in ((r - 1, c), (r, c + 1), (r + 1, c), (r, c - 1)):
        near = cycle.position(sub)
        if near >= 0:
            out.append(near)
    return out


@dataclass
class Traffic:
    """One robot's side of the deconfliction: its body's place (which differs from its
    plan's place while it is aside), the way back, and its counts."""

    robot: int
    cycle: Cycle
    at: int
    back: list[int] = field(default_factory=list)  # places to walk back through, last first
    counts: TrafficCounts = field(default_factory=TrafficCounts)
    _held: bool = False
    _aside_for: Peer | None = None  # the body with lost next places this one stepped aside for

    def ahead(self, route: Sequence[int]) -> tuple[int, ...]:
        """The next places this body is to walk: back to its plan, then ``route`` (nothing
        when the route is empty: a parked robot aside stays aside)."""
        if not route:
            return ()
        if self._want(route[0]) == route[0]:
            return tuple(route[:LOOK])
        return (*reversed(self.back), *route[:LOOK])[:LOOK]

    def walk(self, route: Sequence[int]) -> tuple[int, ...]:
        """The whole walk left from where the body stands: the way back to the plan (if it
        is needed), then ``route`` (a re-plan starts from it: :meth:`rejoin`)."""
        if not route or not self.returning(route):
            return tuple(route)
        return (*reversed(self.back), *route)

    def rejoin(self) -> None:
        """A re-plan starts from where the body stands: forget the way back."""
        self.back.clear()
        self._aside_for = None

    def decide(self, plan_next: int | None, peers: Sequence[Peer]) -> Step:
        """This step's move given the plan's next place (None: nothing to walk)."""
        occupant = {p.position: p for p in peers}
        want = self._want(plan_next)
        if want is None:
            return self._make_way(occupant, peers)
        if want == self.at:
            return Go(want, on_plan=True)  # the plan walks on from where the body stands
        if self._aside_for is not None:
            if self.back and self._aside_for in peers:
                # stepped aside for a body whose next places are lost: wait here until it
                # moves or is heard of (walking back at once, the two would take turns)
                return self._hold(self._aside_for)
            self._aside_for = None
        blocker = occupant.get(want)
        on_plan = want == plan_next
        if blocker is None and (on_plan or not self._gives_way(want, peers)):
            self._held = False
            return Go(want, on_plan=on_plan)
        if blocker is not None:
            ring = self._ring(want, occupant)
            if ring is None and blocker.lost:
                # it may wait for this robot: waiting for it too, both would wait for good;
                # where its view of this robot is right it sees the ring and names the same
                # yielder
                ring = [blocker]
            if ring is not None and self._yielder(ring, occupant) == self.robot:
                aside = self._aside(occupant, peers, avoid=want)
                if aside is not None:
                    self._held = False
                    self._aside_for = blocker if blocker.lost else None
                    return Go(aside, on_plan=False)
        return self._hold(blocker)

    def _hold(self, blocker: Peer | None) -> Hold:
        if not self._held:
            self._held = True
            self.counts.waits += 1
        return Hold(None if blocker is None else blocker.robot)

    def returning(self, route: Sequence[int]) -> bool:
        """True while the body's next place is on its way back (see :meth:`ahead`)."""
        return bool(route) and self._want(route[0]) != route[0]

    def peer(self, route: Sequence[int]) -> Peer:
        """This robot as the others see it, walking ``route`` next."""
        return Peer(self.robot, self.at, self.ahead(route), self.returning(route))

    def _gives_way(self, want: int, peers: Sequence[Peer]) -> bool:
        """A way back gives way to a robot about to enter the same place on its plan, and
        to a lower robot id on its own way back."""
        return any(p.ahead[:1] == (want,) and (not p.returning or p.robot < self.robot)
                   for p in peers)

    def _want(self, plan_next: int | None) -> int | None:
        if plan_next is None:
            return None
        if self.back and plan_next != self.at \
                and plan_next not in neighbours(self.cycle, self.at):
            return self.back[-1]
        return plan_next

    def _make_way(self, occupant: dict[int, Peer], peers: Sequence[Peer]) -> Step:
        self._held = False
        if not any(p.ahead[:1] == (self.at,) for p in peers):
            return Hold()
        aside = self._aside(occupant, peers, avoid=None)
        return Hold() if aside is None else Go(aside, on_plan=False)

    def _ring(self, want: int, occupant: dict[int, Peer]) -> list[Peer] | None:
        """The robots waiting on each other from ``want`` back to this one, if they do."""
        ring: list[Peer] = []
        place = want
        while (peer := occupant.get(place)) is not None and len(ring) <= len(occupant):
            ring.append(peer)
            if not peer.ahead:
                return None
            place = peer.ahead[0]
            if place == self.at:
                return ring
        return None

    def _yielder(self, ring: list[Peer], occupant: dict[int, Peer]) -> int | None:
        """Highest robot id of the ring (this one included) with a free place beside it:
        every member computes the same from the same knowledge."""
        bodies = {*occupant, self.at}
        members = [(self.robot, self.at), *((p.robot, p.position) for p in ring)]
        for robot, place in sorted(members, reverse=True):
            if any(n not in bodies for n in neighbours(self.cycle, place)):
                return robot
        return None

    def _aside(self, occupant: dict[int, Peer], peers: Sequence[Peer],
               avoid: int | None) -> int | None:
        """A free neighbouring place, the one latest on (best: off) the others' next places."""
        free = [n for n in neighbours(self.cycle, self.at) if n not in occupant and n != avoid]
        if not free:
            return None

        def soonest(place: int) -> int:
            return min((p.ahead.index(place) for p in peers if place in p.ahead),
                       default=LOOK)

        return max(free, key=lambda n: (soonest(n), n not in self.back))

    def moved(self, step: Go) -> None:
        """The body made ``step``."""
        if not step.on_plan:
            self.counts.detours += 1
            if self.back and step.target == self.back[-1]:
                self.back.pop()
            else:
                self.back.append(self.at)
        else:
            self.back.clear()
            self._aside_for = None
        self.at = step.target

    def bumped(self) -> None:
        """The world refused the last Go: a body was in the way after all."""
        self.counts.bumps += 1
        self._aside_for = None
