"""Who takes part in the mission: the survivors' agreement on one participant set (sans I/O).

A robot may die before it announces its start, after some peers heard it and before others
did, or boot so late that the others have started without it. Waiting for every one of the
``k`` robots would stall the fleet on the first of these; planning with whatever each robot
happened to hear would make robots plan for different teams. So the gather ends with an
agreement:

1. A robot is *ready* once every robot is settled: its start is known (heard from it, or in a
   peer's proposal, which restates what a dead robot said), or it is known dead, or it was
   never heard within the boot timeout (*absent*).
2. A ready robot proposes the set of robots whose start it knows (dead ones included: their
   sections are taken over like any death in flight) in its RobotStatus ``roster``.
   Proposals only grow: each is the union of everything heard, peers' proposals included.
3. It *agrees* once every live member of its proposal proposes the same set, and from then
   on announces that set (in any state after "gathering") and never changes it.
4. A committed set seen from a peer wins over one's own proposal; a robot not in it stands
   down (it was heard too late and must not double-cover what the others divided).

Because proposals only grow, two robots that share a live member cannot commit different
sets: each would have had to see the other's final proposal equal to its own.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass

from bus.messages import RobotStatus
from planner.types import SubCell

Roster = dict[int, SubCell]  # robot -> start, in robot-id order once sorted
WireRoster = tuple[tuple[int, int, int], ...]
GATHERING = "gathering"


def to_wire(roster: Mapping[int, SubCell]) -> WireRoster:
    return tuple((robot, start[0], start[1]) for robot, start in sorted(roster.items()))


def from_wire(wire: WireRoster) -> Roster:
    return {robot: (row, col) for robot, row, col in wire}


@dataclass(frozen=True)
class Waiting:
    """Not yet: ``unsettled`` robots are neither heard, dead nor absent; ``disagreeing``
    live members have not proposed the same set yet."""

    proposal: Roster | None
    unsettled: tuple[int, ...]
    disagreeing: tuple[int, ...]

    def describe(self) -> str:
        if self.unsettled:
            return f"robots {list(self.unsettled)} did not announce their start"
        return (f"robots {list(self.disagreeing)} did not agree on the participants "
                f"{sorted(self.proposal or {})}")


@dataclass(frozen=True)
class Agreed:
    roster: Roster
    absent: tuple[int, ...]  # expected robots that take no part (never heard, not in it)


@dataclass(frozen=True)
class StandDown:
    roster: Roster
    decided_by: int


Outcome = Waiting | Agreed | StandDown


def decide(me: int, my_start: SubCell, k: int, statuses: Mapping[int, RobotStatus],
           dead: Collection[int], boot_over: bool) -> Outcome:
    """One step of the agreement for robot ``me`` from what it has heard so far.

    ``statuses`` are the peers' newest statuses (one of ``me`` is ignored), ``dead`` the
    robots known dead, ``boot_over`` whether the boot timeout has passed (unheard robots are
    then absent)."""
    peers = {r: s for r, s in statuses.items() if r != me and 0 <= r < k}
    for robot, status in sorted(peers.items()):
        if status.state != GATHERING and status.roster:
            committed = from_wire(status.roster)
            if me in committed:
                return Agreed(committed, _absent(committed, k))
            return StandDown(committed, robot)
    known: Roster = {me: my_start}
    merged: set[WireRoster] = set()  # most peers propose the same set: merge each one once
    for robot, status in sorted(peers.items()):
        if status.state != GATHERING:
            continue  # it stood down or ended without agreeing: not a participant
        known.setdefault(robot, (status.start[0], status.start[1]))
        if status.roster in merged:
            continue  # its members were set by an earlier peer, in this same order
        merged.add(status.roster)
        for member, start in sorted(from_wire(status.roster).items()):
            if 0 <= member < k:
                known.setdefault(member, start)
    unsettled = tuple(r for r in range(k)
                      if r not in known and r not in dead and not boot_over)
    if unsettled:
        return Waiting(None, unsettled, ())
    # This runs on every status heard, over every peer: a roster equal on the wire to
    # the proposal (the usual case) agrees without being rebuilt as a dict (k^2 per news).
    wire = to_wire(known)
    disagreeing = tuple(r for r in sorted(known) if r != me and r not in dead
                        and (r not in peers or (peers[r].roster != wire
                                                and from_wire(peers[r].roster) != known)))
    if disagreeing:
        return Waiting(known, (), disagreeing)
    return Agreed(known, _absent(known, k))


def _absent(roster: Roster, k: int) -> tuple[int, ...]:
    return tuple(r for r in range(k) if r not in roster)
