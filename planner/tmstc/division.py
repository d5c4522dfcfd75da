"""MSTC*-style division of the STC cycle, balanced by eq. 8 time (TMSTC* section IV-C).

As in MSTC*, the robots keep their order along the cycle and robot j covers the contiguous
stretch [b_j, b_{j+1}) counter-clockwise, after travelling from its start to b_j along a
shortest path of the work-area (that travel counts in its cost, as in MSTC*'s cut value; we
count it in full where the authors' code weighs it by 0.5). We minimise the largest cost
exactly for a given first boundary: binary search on the bound T, and for each T a sweep over
the robots that keeps the set of reachable boundaries (always one interval, so one slice max
per robot). The first boundary is tried at up to CANDIDATES positions between the first
robot's neighbours on the cycle.

Costs are additive along the cycle: eq. 8 drives each straight run from rest, and once a run is
at least v_max^2 / 2a long (0.21 m for the Kobuki, less than one 0.5 m tool width) its time is
length / v_max + v_max / 2a; so a stretch costs moves * d / v_max plus, per twist, one quarter
turn and one v_max / 2a. Shorter tool widths make this an approximation; the reported times
are always planner.metrics.path_time of the actual routes.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from scipy.sparse.csgraph import shortest_path

from planner.cycle import cycle_graph, order_robots, stc_cycle
from planner.metrics import KOBUKI, KinematicParams, path_time
from planner.tmstc.types import Division, RobotRoute
from planner.types import Cycle, IntArray, SpanningTree, SubCell

CANDIDATES = 24
SEARCH_STEPS = 40
FloatArray = np.ndarray


@dataclass(frozen=True)
class CostModel:
    """Additive route cost: per move, per twist (turn plus restart), once per driven route."""

    move: float
    twist: float
    run: float
    quarter: float

    @staticmethod
    def of(params: KinematicParams) -> CostModel:
        d = params.tool_width
        run = params.run_time(d) - d / params.v_max
        return CostModel(move=d / params.v_max, twist=params.quarter_turn_time + run, run=run,
                         quarter=params.quarter_turn_time)


MOVES = CostModel(move=1.0, twist=0.0, run=0.0, quarter=0.0)


def _headings(path: IntArray) -> IntArray:
    """Heading code (3 * (dr + 1) + dc + 1) of the move leaving each cycle position."""
    step = np.roll(path, -1, axis=0) - path
    return 3 * (step[:, 0] + 1) + step[:, 1] + 1


class _Travel:
    """Shortest paths from every start over the cycle's sub-cells (node id = cycle index)."""

    def __init__(self, cycle: Cycle, depots: IntArray) -> None:
        dist, pred = shortest_path(cycle_graph(cycle), directed=False, unweighted=True,
                                   indices=depots, return_predecessors=True)
        self.dist = np.asarray(dist).astype(np.int64)
        self.pred = np.asarray(pred).astype(np.int64)
        self.path = cycle.path
        self.twists, self.last = self._twists()

    def _twists(self) -> tuple[IntArray, IntArray]:
        """Per (robot, node): heading changes along the travel path, and its last heading."""
        pred = self.pred
        rows = np.arange(pred.shape[0])[:, None]
        has = pred >= 0
        safe = np.where(has, pred, np.arange(pred.shape[1])[None, :])
        step = self.path[None, :, :] - self.path[safe]
        head = 3 * (step[..., 0] + 1) + step[..., 1] + 1
        prev_head = head[rows, safe]
        weight = (has & (pred[rows, safe] >= 0) & (head != prev_head)).astype(np.int64)
        jump = safe
        for _ in range(max(1, math.ceil(math.log2(max(2, int(self.dist.max()) + 1))))):
            weight = weight + np.take_along_axis(weight, jump, axis=1)
            jump = np.take_along_axis(jump, jump, axis=1)
        return weight, np.where(has, head, -1)

    def cost(self, j: int, model: CostModel, cycle_heading: IntArray) -> FloatArray:
        """Cost of travel to each node, plus how the junction with the stretch changes it."""
        dist, tw = self.dist[j], self.twists[j]
        base = np.where(dist > 0, dist * model.move + model.run + tw * model.twist, 0.0)
        last = self.last[j]
        same = last == cycle_heading
        reverse = (last >= 0) & (last + cycle_heading == 8)
        quarters = np.where(same, 0, np.where(reverse, 2, 1))
        junction = np.where(dist > 0, np.where(same, -model.run, quarters * model.quarter), 0.0)
        return np.stack([base, junction])

    def route(self, j: int, node: int) -> list[int]:
        out = [node]
        while self.pred[j, out[-1]] >= 0:
            out.append(int(self.pred[j, out[-1]]))
        return out[::-1]


class _Sweep:
    """Feasibility sweeps for one cost model (private)."""

    def __init__(self, cycle: Cycle, travel: _Travel, order: list[int], model: CostModel) -> None:
        n = cycle.n
        self.n = n
        heading = _headings(cycle.path)
        twist = (heading != np.roll(heading, 1)).astype(np.int64)
        twist2 = np.concatenate([twist, twist])
        tcum = np.concatenate([[0], np.cumsum(twist2)])
        self.twists = int(twist.sum())
        self.prefix = np.arange(2 * n + 1) * model.move + tcum * model.twist
        self.offset = self.prefix[:-1] + twist2 * model.twist - model.run
        self.travel: list[tuple[np.ndarray, np.ndarray]] = []
        for slot in range(len(order)):
            base, junction = travel.cost(slot, model, heading)
            base2 = np.concatenate([base, base])
            # thr(s) = bound - travel - junction + offset: prefix[e] <= thr means e fits
            shift = self.offset - base2 - np.concatenate([junction, junction])
            self.travel.append((base2, shift))
        self.linear = model.twist == 0.0
        self.move = model.move
        self.line = np.arange(2 * n)
        self.limit = np.minimum(self.line + n - 1, 2 * n - 1)
        self.quarter = model.quarter

    def reach(self, j: int, bound: float) -> IntArray:
        """Largest next boundary from each start position under ``bound`` (2n + 1 entries)."""
        n = self.n
        base, shift = self.travel[j]
        thr = bound + shift
        if self.linear:
            last = np.floor(thr / self.move).astype(np.int64)  # prefix[e] is e * move
        else:
            last = np.searchsorted(self.prefix, thr, side="right") - 1
        last = np.minimum(last, self.limit)
        out = np.where(last > self.line, last + 1,
                       np.where(base <= bound, self.line + 1, self.line))
        return np.concatenate([out, [2 * n]])

    def frontiers(self, bound: float, start: int) -> tuple[list[int], list[IntArray]]:
        """Largest feasible boundary after each robot, first boundary ``start``.

        The feasible positions of each boundary form one interval [start, R_j]: every s in
        it reaches [s, reach(s)], and intervals that each contain their own left end, with
        the left ends filling an interval, union to one interval. So R_{j+1} is the largest
        reach over [start, R_j] (and at least R_j: a robot may cover nothing).
        """
        frontier, reaches = [start], []
        for j in range(len(self.travel)):
            reach = self.reach(j, bound)
            frontier.append(max(frontier[-1], int(reach[start:frontier[-1] + 1].max())))
            reaches.append(reach)
        return frontier, reaches

    def feasible(self, bound: float, starts: IntArray) -> bool:
        reaches = [self.reach(j, bound) for j in range(len(self.travel))]
        for start in starts.tolist():
            right = start
            for reach in reaches:
                right = max(right, int(reach[start:right + 1].max()))
            if right >= start + self.n:
                return True
        return False

    def boundaries(self, bound: float, starts: IntArray) -> list[int] | None:
        for start in starts.tolist():
            frontier, reaches = self.frontiers(bound, start)
            if frontier[-1] < start + self.n:
                continue
            cuts = [start + self.n]
            for j in range(len(reaches) - 1, -1, -1):
                s = np.arange(start, frontier[j] + 1)
                fits = (s <= cuts[-1]) & (reaches[j][start:frontier[j] + 1] >= cuts[-1])
                cuts.append(int(s[fits].max()))
            return cuts[::-1]
        return None


def _candidates(positions: list[int], n: int) -> IntArray:
    """First-boundary positions to try: between the first robot's cycle neighbours."""
    first = positions[0]
    before = positions[-1] - n if len(positions) > 1 else first - n + 1
    after = positions[1] if len(positions) > 1 else first
    span = np.unique(np.linspace(before + 1, after, CANDIDATES).round().astype(np.int64))
    rest = np.setdiff1d(span % n, [first])
    return np.concatenate([[first], rest]).astype(np.int64)


def _balanced_cuts(sweep: _Sweep, starts: IntArray, lo: float, hi: float, *,
                   integral: bool) -> list[int]:
    """Boundaries that minimise the largest cost; ``hi`` must be feasible, ``lo`` not."""
    for _ in range(SEARCH_STEPS):
        if hi - lo <= (1.0 if integral else hi * 1e-4):
            break
        mid = math.floor(0.5 * (lo + hi)) if integral else 0.5 * (lo + hi)
        if sweep.feasible(mid, starts):
            hi = mid
        else:
            lo = mid
    cuts = sweep.boundaries(hi, starts)
    assert cuts is not None  # hi stays feasible throughout
    return cuts


def _cost_of(sweep: _Sweep, cuts: list[int]) -> float:
    """The largest model cost of a division (the bound it is feasible under)."""
    worst = 0.0
    for j in range(len(cuts) - 1):
        s, end = cuts[j], cuts[j + 1]
        base, shift = sweep.travel[j]
        if end > s + 1:
            # cost = travel + junction + prefix[e] - offset[s] = prefix[e] - shift[s]
            worst = max(worst, float(sweep.prefix[end - 1] - shift[s]))
        elif end == s + 1:
            worst = max(worst, float(base[s]))
    return worst


def _routes(cycle: Cycle, travel: _Travel, order: list[int], starts: Sequence[SubCell],
            cuts: list[int], params: KinematicParams) -> tuple[RobotRoute, ...]:
    n = cycle.n
    routes: dict[int, RobotRoute] = {}
    for slot, robot in enumerate(order):
        first, end = cuts[slot], cuts[slot + 1]
        nodes = [int(cycle.index[starts[robot]])]
        moves = 0
        if end > first:
            nodes = travel.route(slot, first % n)
            moves = len(nodes) - 1
            nodes += [(first + i) % n for i in range(1, end - first)]
        path = tuple((int(cycle.path[i][0]), int(cycle.path[i][1])) for i in nodes)
        routes[robot] = RobotRoute(robot=robot, start=(int(starts[robot][0]),
                                                       int(starts[robot][1])),
                                   first=first % n, covered=max(0, end - first), travel=moves,
                                   path=path, time=path_time(path, params))
    return tuple(routes[r] for r in range(len(starts)))


def divide(tree: SpanningTree, starts: Sequence[SubCell], *, balance: str = "time",
           params: KinematicParams = KOBUKI) -> Division:
    """Split the STC cycle of ``tree`` among robots starting at ``starts`` (sub-cells).

    ``balance="moves"`` minimises the largest number of moves (MSTC*); ``"time"`` minimises
    the largest eq. 8 time, and returns the moves-balanced split instead whenever that one
    happens to be faster under path_time, so it is never slower than it.
    """
    if balance not in ("time", "moves"):
        raise ValueError(f"balance must be 'time' or 'moves', got {balance!r}")
    cycle = stc_cycle(tree)
    order = order_robots(cycle, list(starts))
    positions = [int(cycle.index[starts[r]]) for r in order]
    travel = _Travel(cycle, np.asarray(positions))
    first = _candidates(positions, cycle.n)
    n, k = cycle.n, len(starts)
    # below the average no split is feasible; cutting at the starts always is
    gaps = np.diff(np.asarray([*positions, positions[0] + n]))
    moves = _Sweep(cycle, travel, order, MOVES)
    cuts = _balanced_cuts(moves, first, math.ceil((n - k) / k) - 1.0, float(gaps.max()),
                          integral=True)
    by_moves = _routes(cycle, travel, order, starts, cuts, params)
    if balance == "moves":
        return Division("moves", by_moves)
    model = CostModel.of(params)
    timed = _Sweep(cycle, travel, order, model)
    total = (n - k) * model.move + (timed.twists - k) * model.twist - k * model.run
    # the moves-balanced cuts bound the time search from above (same first candidates)
    hi = _cost_of(timed, cuts) * (1 + 1e-9) + 1e-9
    by_time = _routes(cycle, travel, order, starts,
                      _balanced_cuts(timed, first, min(hi, total / k) * (1 - 1e-9), hi,
                                     integral=False), params)
    if max(r.time for r in by_moves) < max(r.time for r in by_time):
        return Division("time", by_moves)
    return Division("time", by_time)
