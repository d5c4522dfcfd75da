"""The claim protocol for contested cells (Alg. 2 lines 15 and 34).

A robot that wants cell Q broadcasts a claim and waits ``claim_wait`` time units. It then wins
unless, by that moment, it has heard that a live robot already owns Q (a tree edge into Q) or
a live robot claimed Q with a higher priority. With every message delivered within ``D`` time
units, ``claim_wait >= 2 D`` makes the outcome safe: two claims at most D apart hear each other
before either decides, and a claim made later than that hears the earlier winner's tree edge
before it decides (see docs/ormstc.md for the argument). Claims of robots known dead are
ignored, so a robot dying mid-claim blocks nobody once its death is known. A heard claim also
expires ``ttl`` after it was heard: by then its robot has decided and, had it won, its tree
edge has arrived, so an old losing claim cannot block a later one forever.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from planner.ormstc.types import Cell, Priority

PriorityKey = tuple[int, int]


def priority_key(mode: Priority, robot: int, covered: int) -> PriorityKey:
    """Larger wins: the robot id, or fewest covered cells with the id as tie-break."""
    if mode is Priority.FEWEST:
        return (-covered, robot)
    return (0, robot)


@dataclass(frozen=True)
class ClaimOutcome:
    won: bool
    winner: int | None  # the robot believed to hold the cell when the claim is lost


@dataclass
class ClaimBook:
    """Claims heard per cell, cleared when the cell's tree edge is heard."""

    mode: Priority
    ttl: float = math.inf
    pending: dict[Cell, dict[int, tuple[PriorityKey, float]]] = field(default_factory=dict)

    def hear(self, cell: Cell, robot: int, covered: int, now: float = 0.0) -> None:
        key = priority_key(self.mode, robot, covered)
        self.pending.setdefault(cell, {})[robot] = (key, now + self.ttl)

    def settle(self, cell: Cell) -> None:
        """A tree edge into ``cell`` was heard: its claims are decided."""
        self.pending.pop(cell, None)

    def leader(self, cell: Cell, dead: set[int] | frozenset[int],
               now: float = 0.0) -> int | None:
        """The live claimant with the highest priority among unexpired claims, if any."""
        claims = self.pending.get(cell)
        if not claims:
            return None
        live = [(key, robot) for robot, (key, expires) in claims.items()
                if robot not in dead and expires >= now]
        return max(live)[1] if live else None

    def claimed_by_any(self, cell: Cell, robots: set[int] | frozenset[int]) -> bool:
        """Whether one of ``robots`` has a claim on ``cell`` heard and not settled."""
        return not robots.isdisjoint(self.pending.get(cell, ()))

    def decide(self, cell: Cell, me: int, owner: int | None,
               dead: set[int] | frozenset[int], now: float = 0.0) -> ClaimOutcome:
        """Outcome of my claim on ``cell`` at the end of its wait; forgets my claim.

        ``owner`` is the live robot other than me known to own the cell, if any.
        """
        if owner is not None and owner != me:
            outcome = ClaimOutcome(False, owner)
        else:
            best = self.leader(cell, dead, now)
            outcome = ClaimOutcome(best == me or best is None, best)
        claims = self.pending.get(cell)
        if claims is not None:
            claims.pop(me, None)
        return outcome
