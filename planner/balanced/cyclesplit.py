"""Split one STC cycle into stretches that any robot may take (issue 14, item 3; beyond the papers).

Every robot walks a shortest sub-cell path to one end of a stretch of the cycle and covers
the stretch from there, forwards or backwards; its cost is that walk plus the stretch's
length minus one. Unlike MSTC* (planner.tmstc.division, where the robots keep their order
along the cycle) any robot may take any stretch, so a robot can jump to a part of the cycle
that winds past it. This is what wins where balanced regions cannot be grown round the
starts (mazes: every cell a cut cell; a room behind a door): the registry's planner
(``plan.plan_for``) keeps it only when its makespan beats the regions and opt.

For a bound T, stretches are handed out along the cycle from a first cut: at position a,
every unused robot's *reach* is the farthest end it can cover within T (forwards: enter at
a; backwards: enter at the end, whose walk grows by at most one per cycle step, so the
farthest end is a binary search). The robot taken is the one among the ``LOOKAHEAD``
farthest-reaching after which the next picks (DEPTH of them, chosen the same way) get
farthest; plain farthest-reach is myopic (a robot that could serve a later stretch just as
well uses itself up early). Feasibility is searched on T (binary search) from a few first cuts; the
greedy is a heuristic, so a T it cannot fill may still be feasible, which only costs
quality, never validity. The bound ``below`` (the best plan known) skips first cuts that
cannot beat it with one test.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.balanced.assign import start_distances
from planner.balanced.relocate import sub_cell_route
from planner.grid import WorkArea
from planner.types import BoolArray, Cycle, Int32Array, IntArray, RobotPlan, SubCell

LOOKAHEAD = 3  # farthest-reaching robots compared at each pick (3 and 8 tied: issue 14)
DEPTH = 2  # picks looked ahead past each of them, below MANY robots (1 from MANY)
FIRST_CUTS = 8  # first cuts tried, evenly round the cycle
FIRST_CUTS_MANY = 2  # from MANY robots, where one greedy costs k reach scans of k robots
MANY = 50


@dataclass(frozen=True)
class Stretch:
    """Robot ``robot`` covers cycle indices first .. end - 1 (mod n), entering at ``first``
    when ``forward`` and at ``end - 1`` otherwise."""

    robot: int
    first: int
    end: int
    forward: bool

    @property
    def entry(self) -> int:
        return self.first if self.forward else self.end - 1


class CycleReach:
    """Reaches of the robots along a cycle, from their walks to every cycle index."""

    def __init__(self, walks: IntArray | Int32Array, *, depth: int = 1) -> None:
        """``walks[j, i]``: robot j's shortest walk to cycle index i (any large value: none).

        Consecutive cycle indices are neighbouring sub-cells, so a row changes by at most one
        per index and ``walks[j, i] + i`` never decreases (the backward reach's search).
        """
        self.walks = np.asarray(walks)  # int32 from start_distances: half the memory
        self.k, self.n = self.walks.shape
        self.depth = depth  # picks looked ahead past each candidate

    def reach(self, at: int, bound: int, rows: IntArray) -> tuple[IntArray, BoolArray]:
        """For robots ``rows``: the farthest end (exclusive, on the unrolled line, at most
        at + n) each covers from ``at`` within ``bound`` moves (``at`` if none), and whether
        it enters forwards."""
        n = self.n
        walk = self.walks[rows, at % n].astype(np.int64)
        forward = np.where(walk <= bound, at + bound + 1 - walk, at)
        # backwards: the largest x in [at, at + bound] with walk(x) + x - at <= bound
        lo = np.full(len(rows), at - 1, dtype=np.int64)
        hi = np.full(len(rows), at + min(bound, n - 1), dtype=np.int64)
        while True:
            open_ = hi > lo
            if not open_.any():
                break
            mid = (lo + hi + 1) // 2
            fits = self.walks[rows, mid % n].astype(np.int64) + mid - at <= bound
            lo = np.where(open_ & fits, mid, lo)
            hi = np.where(open_ & ~fits, mid - 1, hi)
        backward = lo + 1
        return np.minimum(np.maximum(forward, backward), at + n), forward >= backward

    def stretches(self, bound: int, first: int) -> list[Stretch] | None:
        """Stretches covering the cycle from cut ``first``, each within ``bound``; None if
        the greedy runs out of robots."""
        end = first + self.n
        free = np.ones(self.k, dtype=bool)
        at = first
        out: list[Stretch] = []
        while at < end:
            rows = np.flatnonzero(free)
            if rows.size == 0:
                return None
            reach, forward = self.reach(at, bound, rows)
            pick = int(np.argmax(reach))
            if reach[pick] <= at:
                return None
            if reach[pick] < end and rows.size > 1:
                pick = self._look_ahead(bound, at, rows, reach, end)
            robot, stop = int(rows[pick]), int(reach[pick])
            free[robot] = False
            out.append(Stretch(robot, at, min(stop, end), bool(forward[pick])))
            at = stop
        return out

    def _look_ahead(self, bound: int, at: int, rows: IntArray, reach: IntArray,
                    end: int) -> int:
        """Index into ``rows`` of the robot to take: among the LOOKAHEAD farthest-reaching
        (that reach past ``at``), the one after which the next ``self.depth`` picks (chosen
        the same way) get farthest."""
        best, best_after = -1, -1
        for pick in np.argsort(-reach, kind="stable")[:LOOKAHEAD].tolist():
            if reach[pick] <= at:
                break  # it would cover nothing: never worth a robot
            after = self._farthest(bound, int(reach[pick]), np.delete(rows, pick), end,
                                   self.depth)
            if after > best_after:
                best, best_after = pick, after
                if after >= end:
                    break
        return best

    def _farthest(self, bound: int, at: int, rows: IntArray, end: int, depth: int) -> int:
        if at >= end or depth == 0 or rows.size == 0:
            return at
        reach = self.reach(at, bound, rows)[0]
        if depth == 1:
            return int(reach.max())
        farthest = at
        for pick in np.argsort(-reach, kind="stable")[:LOOKAHEAD].tolist():
            if reach[pick] <= at:
                break
            farthest = max(farthest, self._farthest(bound, int(reach[pick]),
                                                    np.delete(rows, pick), end, depth - 1))
            if farthest >= end:
                break
        return farthest

    def best(self, lower: int, below: int, firsts: IntArray) -> tuple[int, list[Stretch]] | None:
        """The smallest bound in [lower, below) the greedy fills from one of ``firsts``, with
        its stretches; None if none does."""
        found: tuple[int, list[Stretch]] | None = None
        for first in firsts.tolist():
            top = below - 1 if found is None else found[0] - 1
            if top < lower:
                break
            at_top = self.stretches(top, first)
            if at_top is None:
                continue
            lo, hi, fill = lower - 1, top, at_top  # lo fails (or is below lower), hi fills
            while hi - lo > 1:
                mid = (lo + hi) // 2
                got = self.stretches(mid, first)
                if got is None:
                    lo = mid
                else:
                    hi, fill = mid, got
            found = (hi, fill)
        return found


def give_idle_robots_their_starts(stretches: list[Stretch], positions: list[int],
                                  n: int) -> list[Stretch]:
    """Every robot a stretch, no cost grown. A robot left out takes the part of the stretch
    holding its start from its start on (in that stretch's direction; entered with no walk);
    where its start is the stretch's entry it takes the whole stretch, and the owner, who
    walked there, is left out in turn. Each such swap leaves one walking robot fewer, so it
    ends."""
    out = list(stretches)
    idle = sorted(set(range(len(positions))) - {s.robot for s in out})
    while idle:
        robot = idle.pop(0)
        at = positions[robot]
        i, s = next((i, s) for i, s in enumerate(out) if (at - s.first) % n < s.end - s.first)
        spot = s.first + (at - s.first) % n
        if spot == s.entry:
            out[i] = Stretch(robot, s.first, s.end, s.forward)
            idle.append(s.robot)
        elif s.forward:
            out[i] = Stretch(s.robot, s.first, spot, True)
            out.append(Stretch(robot, spot, s.end, True))
        else:
            out[i] = Stretch(s.robot, spot + 1, s.end, False)
            out.append(Stretch(robot, s.first, spot + 1, False))
    return out


def split_cycle(area: WorkArea, cycle: Cycle, *, below: int) -> tuple[RobotPlan, ...] | None:
    """Robot plans (walk, then stretch) of a split of ``cycle`` whose makespan is under
    ``below``, or None if the greedy finds none. ``cycle`` must run through the area's
    sub-cells."""
    k = len(area.starts)
    lower = -(-area.n // k) - 1
    if below <= lower:
        return None
    w = area.sub_cells.shape[1]
    flat = cycle.path[:, 0] * w + cycle.path[:, 1]
    walks = start_distances(area, limit=below)[:, flat]
    few = k < MANY
    reach = CycleReach(walks, depth=DEPTH if few else 1)
    cuts = FIRST_CUTS if few else FIRST_CUTS_MANY
    firsts = np.unique(np.linspace(0, cycle.n, cuts, endpoint=False).astype(np.int64))
    found = reach.best(lower, below, firsts)
    if found is None:
        return None
    positions = [cycle.position(s) for s in area.starts]
    stretches = give_idle_robots_their_starts(found[1], positions, cycle.n)
    plans: dict[int, RobotPlan] = {}
    for s in stretches:
        start = area.starts[s.robot]
        entry = cycle.at(s.entry)
        walk = sub_cell_route(area, start, {entry}) if entry != start else (start,)
        assert walk is not None  # the cycle is the area's: every sub-cell is reachable
        order = range(s.first, s.end) if s.forward else range(s.end - 1, s.first - 1, -1)
        stretch: list[SubCell] = [cycle.at(i) for i in order]
        plans[s.robot] = RobotPlan(robot=s.robot, start=start,
                                   start_index=positions[s.robot], legs=(),
                                   path=walk[:-1] + tuple(stretch), walk_out=len(walk) - 1)
    return tuple(plans[r] for r in range(k))
