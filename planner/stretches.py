"""Cut an ordered walk into stretches any robot may take, to finish as early as possible.

The walk is a cycle (an STC cycle: every robot may start anywhere on it and wrap round) or a
line (the uncovered work of a re-plan, in some order, with gaps between places that are not
neighbours). Robot j covers a stretch by walking a shortest path to one end of it (its walk
to place i is ``walks[j, i]``, plus whatever it must do first) and along the stretch to the
other end; its cost is that walk plus the stretch's length in moves. Two callers:
``planner.balanced.cyclesplit`` (a plan: the tree's cycle among all robots) and
``planner.offline.rebalance`` (a re-plan after a death: the uncovered work among the
survivors).

For a bound T, stretches are handed out along the walk from a first cut: at place a, every
unused robot's *reach* is the farthest end it can cover within T (forwards: enter at a;
backwards: enter at the end, whose walk grows by at most the distance between places, so
``walks[j, x] + position[x]`` never decreases and the farthest end is a binary search). The
robot taken is the one among the ``LOOKAHEAD`` farthest-reaching after which the next picks
(``depth`` of them, chosen the same way) get farthest; plain farthest-reach is myopic (a
robot that could serve a later stretch just as well uses itself up early). The bound is
binary-searched from a few first cuts; the greedy is a heuristic, so a T it cannot fill may
still be feasible, which only costs quality, never validity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.types import BoolArray, Int32Array, IntArray

LOOKAHEAD = 3  # farthest-reaching robots compared at each pick (3 and 8 tied: issue 14)


@dataclass(frozen=True)
class Stretch:
    """Robot ``robot`` covers places first .. end - 1 (mod n on a cycle), entering at
    ``first`` when ``forward`` and at ``end - 1`` otherwise."""

    robot: int
    first: int
    end: int
    forward: bool

    @property
    def entry(self) -> int:
        return self.first if self.forward else self.end - 1


class Reach:
    """Reaches of the robots along a walk of n places, from their walks to every place."""

    def __init__(self, walks: IntArray | Int32Array, *, depth: int = 1,
                 positions: IntArray | None = None) -> None:
        """``walks[j, i]``: what robot j spends before it can start covering at place i (its
        shortest walk there, plus any work it must do first; any large value: never).

        Without ``positions`` the walk is a cycle whose consecutive places are neighbouring
        sub-cells (one move apart, the last next to the first). With ``positions`` it is a
        line: ``positions[i]`` is the moves from place 0 to place i along it (nondecreasing,
        growing at least by the shortest distance between consecutive places).
        """
        self.walks = np.asarray(walks)  # int32 from start_distances: half the memory
        self.k, self.n = self.walks.shape
        self.depth = depth  # picks looked ahead past each candidate
        self.ring = positions is None
        self.positions = None if positions is None else np.asarray(positions, dtype=np.int64)

    def _walk(self, rows: IntArray, at: IntArray | int) -> IntArray:
        place = np.asarray(at) % self.n if self.ring else np.asarray(at)
        return self.walks[rows, place].astype(np.int64)

    def _pos(self, at: IntArray | int) -> IntArray:
        if self.positions is None:
            return np.asarray(at, dtype=np.int64)
        return self.positions[np.asarray(at)]

    def _last(self, at: int, bound: int) -> int:
        """The farthest place a stretch from ``at`` may end on at all (inclusive)."""
        if self.positions is None:
            return at + min(bound, self.n - 1)
        return int(np.searchsorted(self.positions, self.positions[at] + bound, "right")) - 1

    def reach(self, at: int, bound: int, rows: IntArray) -> tuple[IntArray, BoolArray]:
        """For robots ``rows``: the farthest end (exclusive; on a cycle on the unrolled
        line, at most at + n) each covers from ``at`` within ``bound`` moves (``at`` if
        none), and whether it enters forwards."""
        walk = self._walk(rows, at)
        start = int(self._pos(at))
        last = self._last(at, bound)
        if self.positions is None:
            forward = np.where(walk <= bound, at + bound + 1 - walk, at)
        else:
            forward = np.where(walk <= bound, np.searchsorted(
                self.positions, start + bound - walk, "right"), at)
        # backwards: the largest x in [at, last] with walk(x) + pos(x) - pos(at) <= bound
        lo = np.full(len(rows), at - 1, dtype=np.int64)
        hi = np.full(len(rows), last, dtype=np.int64)
        while True:
            open_ = hi > lo
            if not open_.any():
                break
            mid = (lo + hi + 1) // 2
            fits = self._walk(rows, mid) + self._pos(mid) - start <= bound
            lo = np.where(open_ & fits, mid, lo)
            hi = np.where(open_ & ~fits, mid - 1, hi)
        backward = lo + 1
        limit = at + self.n if self.ring else self.n
        return np.minimum(np.maximum(forward, backward), limit), forward >= backward

    def stretches(self, bound: int, first: int) -> list[Stretch] | None:
        """Stretches covering the walk from cut ``first`` (on a line: from ``first`` to its
        end), each within ``bound``; None if the greedy runs out of robots."""
        end = first + self.n if self.ring else self.n
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
