"""Re-balancing after a death: the survivors share the orphaned work instead of one taking
it over in sequence (beyond the papers).

When a robot is known dead, the work nobody alive is still going to do — every uncovered
sub-cell that lies on no survivor's remaining route — is put in the order the plan walks it
(so a dead robot's orphans are the rest of its walk) and cut into contiguous pieces; each
piece is appended to one survivor's route, choosing the number of pieces, their boundaries
and who takes which so that the last survivor finishes as early as possible. Every input is
agreed (the plan, the coverage, each survivor's position and remaining route) and the
computation is integer and tie-broken by fixed orders, so every survivor that holds the same
inputs computes the same re-plan; a piece goes to exactly one survivor, so no sub-cell is
owned by two live robots. A later death re-plans again: the pieces of the newly dead are
orphans like the rest of its route.

Beside that re-plan up to three others are made and the one that finishes first kept: the
whole uncovered work cut anew in the plan's order or along the cycle (with at most
MAX_TAKERS survivors), and balanced regions of it grown from where the survivors stand
(planner.balanced.regrow), whose robots next to the orphans take them and leave their own
far work to their neighbours. The one kept is then refined (planner.offline.refine:
stretches of the last survivor's work moved to another survivor or elsewhere in its own
route, while that finishes sooner); on small areas each is refined and the best kept.

Places are cycle indices of ``cycle`` (the key space of the offline machines); the walks
between pieces and to them are shortest paths over the cycle's sub-cells
(planner.offline.shortest).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from itertools import pairwise
from typing import Literal

import numpy as np

from planner.grid import FAR
from planner.offline.shortest import Grid
from planner.stretches import Reach
from planner.types import BoolArray, Cycle, IntArray, Plan

Recovery = Literal["takeover", "rebalance"]
RECOVERIES: tuple[Recovery, ...] = ("takeover", "rebalance")
# The default of simulate_failures, mstc up and mstc agent: walks are deconflicted
# (planner.offline.traffic), so the re-plan's walks across other regions are safe.
DEFAULT_RECOVERY: Recovery = "rebalance"
# Survivors considered for a piece, nearest (finish time plus travel) first: beyond a dozen,
# a far survivor never shortens the makespan and the assignment grows cubically.
MAX_TAKERS = 12
REFINE_ROUNDS = 24
GREEDY_DEPTH = 2  # picks the re-plan's greedy looks ahead (at most MAX_TAKERS robots)
# The regrown regions: each partition after the first corrects the sizes by the work each
# region of the last one really held (half-covered cells count whole in the partitioner).
# One death on office, mean over 18: 1.266 with one, 1.248 two, 1.237 three, 1.234 four
# (docs/balanced.md).
REGROW_PASSES = 3
# The regions are grown only on areas up to this many sub-cells: a partition of 45 000
# sub-cells at k = 100 costs seconds of CPU on every survivor at once.
REGROW_MAX_SUB_CELLS = 12_000
# The re-plan chosen is refined (planner.offline.refine) on areas up to this size, and on
# small areas with at most MAX_TAKERS survivors every option is, the best then kept: k/2
# deaths on office, 20 seeds, 1.178 x the ideal unrefined, 1.131 with the chosen refined,
# 1.123 with all (docs/balanced.md). A refinement costs 0.02-0.6 s of CPU up to 12 000
# sub-cells, at k = 6 as at k = 100; with many survivors only the chosen one is refined.
# Above 12 000 it cost 0.8-11 s more and shortened one re-plan by 10-17 % (one death at
# 40 %, uneven progress: city 64 x 64 k = 30 334 -> 294 moves, rooms 120 x 120 k = 100
# 381 -> 318; docs/balanced.md): worth it, as from 13 survivors one of them computes the
# re-plan for all (agent.offline.replan.SHARE_FROM). Up to the 47 000 sub-cells of item 4.
REFINE_MAX_SUB_CELLS = 50_000
REFINE_ALL_MAX_SUB_CELLS = 3_000


@dataclass(frozen=True)
class Survivor:
    """A robot believed alive: where it stands and the cycle indices it is still to walk."""

    robot: int
    position: int
    route: tuple[int, ...]

    @property
    def end(self) -> int:
        return self.route[-1] if self.route else self.position


def plan_order(plan: Plan) -> IntArray:
    """Rank of each cycle index in the order the fault-free plan first covers it, robot by
    robot in plan order, each robot's region walk (walk-out excluded) in walk order: the
    orphans of a dead robot, sorted by it, are the rest of its own walk."""
    n = plan.cycle.n
    rank = np.full(n, -1, dtype=np.int64)
    ranked = 0
    for rp in plan.robots:
        for sub in rp.path[rp.walk_out:]:
            index = plan.cycle.position(sub)
            if rank[index] < 0:
                rank[index] = ranked
                ranked += 1
    left = rank < 0  # only a malformed plan leaves any: keep them, in cycle order
    rank[left] = ranked + np.arange(int(left.sum()))
    return rank


def frozen_at(plan: Plan, walked: Mapping[int, int], dead: Collection[int]
              ) -> tuple[BoolArray, list[Survivor]]:
    """What a re-plan starts from when each robot has walked ``walked[robot]`` moves of its
    fault-free path (robots as points, deaths known at once): the covered cycle indices,
    and every robot not in ``dead`` as a survivor. For benchmarks, figures and tests; a
    fleet's comes from its robots' reports (agent.offline.replan)."""
    cycle = plan.cycle
    covered = np.zeros(cycle.n, dtype=bool)
    survivors = []
    for rp in plan.robots:
        walk = [cycle.position(sub) for sub in rp.path]
        at = min(walked[rp.robot], len(walk) - 1)
        covered[walk[:at + 1]] = True
        if rp.robot not in dead:
            survivors.append(Survivor(rp.robot, walk[at], tuple(walk[at + 1:])))
    return covered, survivors


def orphans(covered: BoolArray, survivors: Sequence[Survivor], rank: IntArray) -> list[int]:
    """Uncovered cycle indices on no survivor's route, by ``rank``."""
    planned = np.zeros(covered.shape[0], dtype=bool)
    for s in survivors:
        planned[list(s.route)] = True
    left = np.flatnonzero(~covered & ~planned)
    return [int(i) for i in left[np.argsort(rank[left], kind="stable")]]


@dataclass(frozen=True)
class Replan:
    """Each survivor's route from where it stands, and the one robot that owns (is to
    cover) each uncovered cycle index."""

    routes: dict[int, tuple[int, ...]]
    owner: dict[int, int]

    @property
    def makespan(self) -> int:
        """Moves until the last route is walked."""
        return max((len(r) for r in self.routes.values()), default=0)


@dataclass(frozen=True)
class _Split:
    finish: int  # moves until the last survivor is done
    total: int
    pieces: tuple[tuple[int, int], ...]  # [start, stop) into the orphan list
    takers: tuple[int, ...]  # survivor position in the list, per piece


def rebalance(cycle: Cycle, covered: BoolArray, survivors: Sequence[Survivor],
              rank: IntArray) -> Replan:
    """Each survivor's new route (cycle indices to walk from where it stands).

    The re-plans are compared and the one that finishes first kept (the first on a tie):
    each survivor keeps its route and some append a piece of the orphaned work; or all the
    uncovered work, the survivors' own included, is cut anew (a survivor far from the dead
    robot's region then takes over part of a nearer survivor's); or it is partitioned anew
    into regions grown from the survivors (:func:`_regrown`); the one kept is refined
    (:func:`_refined`). ``covered`` is per cycle index, ``rank`` the order of the work
    (:func:`plan_order`). Survivors are taken in robot-id order whatever order they come
    in, so the result depends only on the inputs.
    """
    survivors = sorted(survivors, key=lambda s: s.robot)
    kept = Replan({s.robot: s.route for s in survivors}, _owners(covered, survivors))
    if not survivors:
        return kept
    grid = Grid(cycle)
    left = orphans(covered, survivors, rank)
    appended = _share(grid, covered, left, survivors, keep=True)
    if appended is None:  # nothing orphaned (the dead robot had finished): keep the routes
        lengths = [len(s.route) for s in survivors]
        appended = (_Split(max(lengths), sum(lengths), (), ()), kept)
    options = [appended]
    if len(survivors) <= MAX_TAKERS:  # beyond, a cut of all the work leaves the rest idle
        uncovered = np.flatnonzero(~covered)
        everything = [int(i) for i in uncovered[np.argsort(rank[uncovered], kind="stable")]]
        for order in (everything, _ring_order(uncovered, cycle.n)):
            cut = _share(grid, covered, order, survivors, keep=False)
            if cut is not None:
                options.append(cut)
    if 0 < cycle.n <= REGROW_MAX_SUB_CELLS:
        options.extend(_regrown(grid, covered, survivors))
    options.sort(key=lambda o: (o[0].finish, o[0].total))  # stable: the first on a tie
    if cycle.n > REFINE_MAX_SUB_CELLS:
        return options[0][1]
    if cycle.n > REFINE_ALL_MAX_SUB_CELLS or len(survivors) > MAX_TAKERS:
        return _refined(grid, covered, survivors, options[0][1])
    polished = [_refined(grid, covered, survivors, replan) for _, replan in options]
    return min(polished, key=lambda r: (r.makespan, sum(map(len, r.routes.values()))))


def _refined(grid: Grid, covered: BoolArray, survivors: list[Survivor], chosen: Replan
             ) -> Replan:
    """``chosen`` with stretches of work moved between survivors (planner.offline.refine),
    if that finishes sooner (or as soon with fewer moves in all)."""
    # Imported here, as the regrown regions are: only a re-plan after a death needs it.
    from planner.offline.refine import refined

    works: list[list[int]] = []
    for s in survivors:
        seen: set[int] = set()
        work = []
        for index in chosen.routes[s.robot]:
            if not covered[index] and chosen.owner.get(index) == s.robot and index not in seen:
                seen.add(index)
                work.append(index)
        works.append(work)
    if sum(map(len, works)) != len(chosen.owner):  # an owned place off its owner's route
        return chosen
    positions = [s.position for s in survivors]
    better = refined(grid, positions, works)
    if better == works:
        return chosen
    walks = _walks_around(grid, positions, better)
    lengths = [len(walk) for walk in walks]
    if (max(lengths), sum(lengths)) >= (chosen.makespan, sum(map(len, chosen.routes.values()))):
        return chosen
    owner = {index: s.robot for s, work in zip(survivors, better, strict=True) for index in work}
    return Replan({s.robot: walk for s, walk in zip(survivors, walks, strict=True)}, owner)


def _regrown(grid: Grid, covered: BoolArray, survivors: list[Survivor]
             ) -> list[tuple[_Split, Replan]]:
    """Regions of the uncovered work grown from the survivors (planner.balanced.regrow),
    each walked in its own order: the best of REGROW_PASSES partitions, or none when no
    such partition exists."""
    # Imported here, not at the top: every offline agent imports this module, and only a
    # re-plan after a death needs the balanced partitioner.
    from planner.balanced.regrow import regrown_work

    positions = [s.position for s in survivors]
    offsets: list[int] | None = None
    best: tuple[_Split, Replan] | None = None
    for _ in range(REGROW_PASSES):
        found = regrown_work(grid.cycle, covered, positions, offsets)
        if found is None:
            break
        walks = _walks_around(grid, [s.position for s in survivors], found.work)
        routes = {s.robot: walk for s, walk in zip(survivors, walks, strict=True)}
        lengths = [len(walk) for walk in walks]
        split = _Split(max(lengths), sum(lengths), (), ())
        if best is None or (split.finish, split.total) < (best[0].finish, best[0].total):
            owner = {i: s.robot for s, work in zip(survivors, found.work, strict=True)
                     for i in work}
            best = (split, Replan(routes, owner))
        gaps = [length - size for length, size in zip(lengths, found.sizes, strict=True)]
        corrected = [g - min(gaps) for g in gaps]
        if corrected == offsets:  # the same partition again
            break
        offsets = corrected
    return [] if best is None else [best]


def _walks_around(grid: Grid, starts: Sequence[int], works: Sequence[Sequence[int]]
                  ) -> list[tuple[int, ...]]:
    """Each robot's walk from ``starts[i]`` along ``works[i]``, around the places where the
    others stop (the end of their work, or their start): a robot parked there for good
    would block the way, and simhw refuses a body into a body."""
    stops = [work[-1] if work else start for start, work in zip(starts, works, strict=True)]
    return [tuple(grid.walk(start, work, frozenset(stops[:i] + stops[i + 1:])))
            for i, (start, work) in enumerate(zip(starts, works, strict=True))]


def _owners(covered: BoolArray, survivors: Sequence[Survivor]) -> dict[int, int]:
    """Uncovered indices on the survivors' routes -> the first survivor (robot order) whose
    route holds it (two routes share one only where a walk-out crosses a region)."""
    owner: dict[int, int] = {}
    for s in survivors:
        for index in s.route:
            if not covered[index]:
                owner.setdefault(index, s.robot)
    return owner


def _ring_order(indices: IntArray, n: int) -> list[int]:
    """Sorted cycle indices rotated to start after the widest gap along the ring."""
    if indices.size == 0:
        return []
    gaps = (np.roll(indices, -1) - indices) % n
    gaps[gaps == 0] = n
    cut = (int(np.argmax(gaps)) + 1) % indices.size
    return [int(i) for i in np.roll(indices, -cut)]


def _share(grid: Grid, covered: BoolArray, work: list[int], survivors: list[Survivor], *,
           keep: bool) -> tuple[_Split, Replan] | None:
    """Cut ``work`` into pieces for ``survivors``, after their routes (``keep``) or instead
    of them; None when there is no work."""
    if not work:
        return None
    steps = [grid.distance(a, b) for a, b in pairwise(work)]
    walked = np.concatenate([[0], np.cumsum(steps, dtype=np.int64)])  # moves to reach work[j]
    loads = np.array([len(s.route) if keep else 0 for s in survivors], dtype=np.int64)
    ends = [s.end if keep else s.position for s in survivors]
    # distances are symmetric: two maps from the work's ends, not one per survivor
    at = grid.cycle.path[np.asarray(ends)]
    reach = np.stack([grid.from_source(o)[at[:, 0], at[:, 1]] for o in (work[0], work[-1])],
                     axis=1)
    nearest = np.argsort(loads + reach.min(axis=1), kind="stable")[:MAX_TAKERS]
    best: _Split | None = None
    for m in range(1, min(len(nearest), len(work)) + 1):
        split = _best_split(grid, work, walked, loads, ends, [int(i) for i in nearest], m)
        if best is None or (split.finish, split.total) < (best.finish, best.total):
            best = split
    assert best is not None
    greedy = _greedy_split(grid, work, walked, loads, ends, [int(i) for i in nearest],
                           below=best.finish)
    if greedy is not None and (greedy.finish, greedy.total) < (best.finish, best.total):
        best = greedy
    routes = {s.robot: s.route if keep else () for s in survivors}
    owner = _owners(covered, survivors) if keep else {}
    oriented = {}
    for (a, b), taker in zip(best.pieces, best.takers, strict=True):
        piece = work[a:b]
        if grid.distance(ends[taker], piece[-1]) < grid.distance(ends[taker], piece[0]):
            piece = piece[::-1]
        oriented[taker] = piece
        owner.update((index, survivors[taker].robot) for index in piece)
    walks = _walks_around(grid, ends, [oriented.get(i, []) for i in range(len(survivors))])
    for taker in oriented:
        s = survivors[taker]
        routes[s.robot] = routes[s.robot] + walks[taker]
    return best, Replan(routes, owner)


def _piece_costs(grid: Grid, work: list[int], walked: IntArray, ends: list[int],
                 pieces: list[tuple[int, int]]) -> IntArray:
    """Moves for each survivor (row) to walk to and along each piece (column)."""
    firsts, lasts = zip(*pieces, strict=True)
    inside = walked[[b - 1 for b in lasts]] - walked[list(firsts)]
    nearer = np.minimum(grid.distances(ends, [work[a] for a in firsts]),
                        grid.distances(ends, [work[b - 1] for b in lasts]))
    return (inside[None, :] + nearer).astype(np.int64)


def _best_split(grid: Grid, work: list[int], walked: IntArray, loads: IntArray,
                ends: list[int], takers: list[int], m: int) -> _Split:
    """``m`` pieces: equal lengths first, then boundaries moved from the piece that ends
    later towards its neighbour, keeping the best split seen."""
    size = len(work)
    bounds = [round(size * j / m) for j in range(m + 1)]
    best: _Split | None = None
    seen: set[tuple[int, ...]] = set()
    for _ in range(REFINE_ROUNDS):
        key = tuple(bounds)
        if key in seen:
            break
        seen.add(key)
        pieces = list(pairwise(bounds))
        costs = _piece_costs(grid, work, walked, [ends[t] for t in takers], pieces)
        costs += loads[takers][:, None]
        rows, finish_of_piece = _bottleneck(costs)
        assigned = {takers[r] for r in rows}
        idle = [int(loads[i]) for i in range(len(loads)) if i not in assigned]
        finish = max([*finish_of_piece.tolist(), *idle])
        split = _Split(int(finish), int(finish_of_piece.sum()), tuple(pieces),
                       tuple(takers[r] for r in rows))
        if best is None or (split.finish, split.total) < (best.finish, best.total):
            best = split
        bounds = _shifted(bounds, finish_of_piece)
    assert best is not None
    return best


def _greedy_split(grid: Grid, work: list[int], walked: IntArray, loads: IntArray,
                  ends: list[int], takers: list[int], *, below: int) -> _Split | None:
    """Pieces handed out along ``work`` by planner.stretches' greedy (any taker any piece,
    entered at either end, after its load), the smallest finish under ``below`` it fills;
    None if it fills none. Beside the equal cut of :func:`_best_split`, it sizes each piece
    to what its taker can do, so a survivor far away takes a short piece."""
    at = grid.cycle.path[np.asarray(work)]
    walks = np.stack([grid.from_source(ends[t])[at[:, 0], at[:, 1]] + loads[t]
                      for t in takers])
    found = Reach(walks, depth=GREEDY_DEPTH, positions=walked).best(0, below, np.zeros(1, int))
    if found is None:
        return None
    pieces = tuple((s.first, s.end) for s in found[1])
    chosen = tuple(takers[s.robot] for s in found[1])
    # its load, the walk to the nearer end, the piece: the equal cut's cost, from ``walks``
    finish = [int(min(walks[s.robot, s.first], walks[s.robot, s.end - 1])
                  + walked[s.end - 1] - walked[s.first]) for s in found[1]]
    idle = [int(loads[i]) for i in range(len(loads)) if i not in set(chosen)]
    return _Split(max(finish + idle), sum(finish), pieces, chosen)


def _shifted(bounds: list[int], finish: IntArray) -> list[int]:
    """Each inner boundary moved by half the finish-time difference of its two pieces (a
    piece entry costs about one move), pieces kept non-empty."""
    out = list(bounds)
    for j in range(1, len(bounds) - 1):
        move = int(finish[j - 1] - finish[j]) // 2
        out[j] = min(max(out[j] - move, out[j - 1] + 1), bounds[j + 1] - 1)
    return out


def _bottleneck(costs: IntArray) -> tuple[list[int], IntArray]:
    """A distinct row per column minimising the largest cost, then the total: (row per
    column, cost per column)."""
    # Imported here, not at the top: every offline agent imports this module (for
    # RECOVERIES), and scipy.optimize costs ~0.45 s of CPU and ~40 MB per process at start-up,
    # which a 100-robot fleet pays 100 times; only a re-plan after a death needs it.
    from scipy.optimize import linear_sum_assignment
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import maximum_bipartite_matching

    cols_n = costs.shape[1]
    values = np.unique(costs)
    low, high = 0, len(values) - 1
    while low < high:
        mid = (low + high) // 2
        graph = csr_matrix((costs <= values[mid]).T.astype(np.int8))
        if int((maximum_bipartite_matching(graph, perm_type="column") >= 0).sum()) == cols_n:
            high = mid
        else:
            low = mid + 1
    allowed = np.where(costs <= values[low], costs, FAR)
    r, c = linear_sum_assignment(allowed.T)  # rows are pieces here
    row_of = [0] * cols_n
    for piece, survivor in zip(r.tolist(), c.tolist(), strict=True):
        row_of[piece] = survivor
    return row_of, np.array([costs[row_of[j], j] for j in range(cols_n)], dtype=np.int64)
