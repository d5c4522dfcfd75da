"""Which entries of a sub-cell were coverage moves: ORMSTC's accounting of revisits.

ORMSTC promises that no sub-cell is entered twice by the coverage walk (paper 004). On real
hardware a robot also enters sub-cells to sense, not to cover: with a thin sonar it steps to
the sub-cell beside it to look at the far half of a neighbouring cell, then steps back
(docs/ormstc.md, sensing); each such step is announced as a LookStep. And the STC walk ends
where it began: the robot re-enters its start once to close its cycle. Simhw's ground truth
counts all of these as visits; here they are told apart, so that only a revisit made by the
walk itself breaks the promise. Pure; reads the fleet model's coverage map.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping
from dataclasses import dataclass

from deploy.monitor.coverage import CoverageMap
from planner.types import SubCell


@dataclass(frozen=True)
class EntryAccount:
    """Entries beyond the first, split by cause."""

    look_steps: int  # entries announced as made only to sense
    closings: tuple[tuple[SubCell, int], ...]  # (start, robot): the walk's closing re-entry
    # sub-cells entered more than once by coverage moves, with the robots of those entries
    # (an entry the record saw counted but not who made it is shown as robot -1)
    covered_twice: tuple[tuple[SubCell, tuple[int, ...]], ...]

    @property
    def coverage_revisits(self) -> int:
        return sum(len(who) - 1 for _, who in self.covered_twice)


UNKNOWN_ROBOT = -1


def account_entries(cover: CoverageMap, starts: Mapping[int, SubCell]) -> EntryAccount:
    """Split every sub-cell's visits into look steps, closing re-entries and coverage entries."""
    home = {cell: robot for robot, cell in starts.items()}
    closings: list[tuple[SubCell, int]] = []
    twice: list[tuple[SubCell, tuple[int, ...]]] = []
    for cell, visits in sorted(cover.visits.items()):
        seen = cover.visitors.get(cell, [])
        looks = cover.looks.get(cell, {})
        walked = {robot: max(entries - looks.get(robot, 0), 0)
                  for robot, entries in Counter(seen).items()}
        unknown = max(visits - len(seen), 0)
        owner = home.get(cell)
        if owner is not None and walked.get(owner, 0) + unknown >= 2:
            # the placement and the closing re-entry; a recording that began late may have
            # only the counts of them, not who made them
            closings.append((cell, owner))
            if walked.get(owner, 0) >= 2:
                walked[owner] -= 1
            else:
                unknown -= 1
        walkers = [r for r, n in sorted(walked.items()) for _ in range(n)]
        walkers += [UNKNOWN_ROBOT] * unknown
        if len(walkers) > 1:
            twice.append((cell, tuple(walkers)))
    look_steps = sum(n for per_robot in cover.looks.values() for n in per_robot.values())
    return EntryAccount(look_steps, tuple(closings), tuple(twice))


def look_revisits(cover: CoverageMap) -> int:
    """How many of the revisits (visits beyond a sub-cell's first) were look steps: a look
    step into a sub-cell not entered before is a first visit, not a revisit, so this part is
    never bigger than the whole."""
    return sum(min(sum(per_robot.values()), max(cover.visits.get(cell, 0) - 1, 0))
               for cell, per_robot in cover.looks.items())

