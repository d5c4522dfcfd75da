"""Re-splitting two neighbouring regions: the move that frees the transfer chains.

Chains pass one cell at a time and a region can only give a cell that is not a cut of its
whole cells, so one-cell-wide strips (weighted Voronoi makes them between robots that start
side by side) block them. Here the union of two neighbouring regions is divided afresh: one
region is regrown as a breadth-first ball from its start inside the union, to the size that
balances the pair, and the other keeps the rest; the result is kept only if both parts are
connected and keep their pinned cells. Balls are compact, so strips turn into blobs.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from planner.balanced.state import PartitionState, splits
from planner.geometry import cell_of

WHOLE = 4


def reshape_pairs(state: PartitionState, tries: int) -> bool:
    """Re-split the most unequal neighbouring pair that can be improved; True if one was.

    At most ``tries`` pairs are attempted (each attempt costs a few passes over the pair).
    """
    pairs = sorted(_neighbour_pairs(state),
                   key=lambda p: state.load[p[0]] - state.load[p[1]])
    for small, big in pairs[:tries]:
        gap = state.load[big] - state.load[small]
        if gap <= WHOLE:
            break
        moved = max(1, gap // (2 * WHOLE))
        # A re-split depends only on the pair's cells, pins and sizes, all of which bump
        # the pair's region versions: one that failed fails again until they change (on a
        # stalled partition the same pairs come up at every try).
        key = (big, small, moved, state.region_version[big], state.region_version[small])
        if key in state.failed_resplits:
            continue
        if _resplit(state, big, small, moved):
            return True
        state.failed_resplits.add(key)
    return False


def _neighbour_pairs(state: PartitionState) -> list[tuple[int, int]]:
    """(smaller, larger) load pairs of regions whose whole cells touch, sorted.

    "Smaller" orders by (load, robot). One vectorised pass over all neighbouring cell
    pairs (numpy), as in relieve._Offers: this runs before every re-split attempt.
    """
    label = np.asarray(state.label, dtype=np.int64)
    load = np.asarray(state.load, dtype=np.int64)
    own = label[state.edge_src]
    other = label[state.edge_dst]
    mask = (own >= 0) & (other >= 0) & (own != other)
    own, other = own[mask], other[mask]
    own_first = (load[own] < load[other]) | ((load[own] == load[other]) & (own < other))
    small = np.where(own_first, own, other)
    big = np.where(own_first, other, own)
    pairs = np.unique(small * state.k + big).tolist()
    return [divmod(p, state.k) for p in pairs]


def _resplit(state: PartitionState, big: int, small: int, moved: int) -> bool:
    union = state.whole[big] | state.whole[small]
    for grower, size in ((small, len(state.whole[small]) + moved),
                         (big, len(state.whole[big]) - moved)):
        other = big if grower == small else small
        ball = _ball(state, union, grower, other, size)
        if ball is None:
            continue
        rest = union - ball
        if _connected_with_pins(state, rest, other):
            _apply(state, big, small, ball if grower == big else rest)
            return True
    return False


def _ball(state: PartitionState, union: set[int], grower: int, other: int,
          size: int) -> set[int] | None:
    """``size`` cells of ``union`` grown from the grower's start, nearest first.

    Taking a cell that cuts the rest of the union also takes the pieces it cuts off from
    the other region's start (the other region could not keep them); never a pinned cell of
    the other region. None unless the ball ends up holding all the grower's pinned cells.
    """
    pins = [u for u in state.whole[grower] if state.pinned(u)]
    if not pins or size < len(pins):
        return None
    blocked = {u for u in state.whole[other] if state.pinned(u)}
    source = _source(state, grower, pins)
    keep = _source(state, other, sorted(blocked))
    dist = _distances(state, union - blocked, source)
    if any(p not in dist for p in pins) or keep < 0:
        return None
    far = _distances(state, union, keep)
    # Nearest to the grower relative to the other region first (a bisector, as in a
    # Voronoi split of the pair), so a tail of the grower far from the other is kept.
    rank = {v: (dist.get(v, 0) - far.get(v, 0), dist.get(v, 0), v) for v in union}
    ball = {source}
    rest = union - ball
    # cells of rest next to the ball that it may take, kept up to date as the ball grows
    around = {v for v in state.neighbours[source] if v in rest and v not in blocked}
    # Frontier cells that failed stay failed: as rest shrinks, what v cuts off from keep
    # only grows (minus what the ball took), so the ball plus it stays over size, and a
    # blocked cell in it stays there (blocked cells never leave rest). Skipping them saves
    # the search round v that would fail again (most of a re-split's cost at k = 300).
    failed: set[int] = set()
    while len(ball) < size:
        for v in sorted(around, key=lambda v: (not state.pinned(v), rank[v])):
            if v in failed:
                continue
            plain = state.locally_removable_from(rest, v) or not splits(rest, state.neighbours, v)
            swallow = {v} if plain else _cut_off(state, rest, v, keep, blocked)
            if not swallow or len(ball) + len(swallow) > size:
                failed.add(v)
                continue
            ball |= swallow
            rest -= swallow
            around -= swallow
            around.update(x for u in swallow for x in state.neighbours[u]
                          if x in rest and x not in blocked)
            break
        else:
            return None
    return ball if all(p in ball for p in pins) else None


def _source(state: PartitionState, robot: int, pins: list[int]) -> int:
    """The robot's start cell when it is a whole cell of its region, else its first pin."""
    home = state.flat(cell_of(state.starts[robot]))
    return home if home in pins else (min(pins) if pins else -1)


def _cut_off(state: PartitionState, rest: set[int], v: int, keep: int,
             blocked: set[int]) -> set[int]:
    """``v`` and what it cuts off from ``keep`` in ``rest`` (empty if that holds a pin)."""
    reached = _distances(state, rest - {v}, keep)
    swallow = rest - reached.keys()
    return set() if swallow & blocked else swallow


def _distances(state: PartitionState, cells: set[int], source: int) -> dict[int, int]:
    dist = {source: 0}
    queue = deque([source])
    while queue:
        u = queue.popleft()
        for v in state.neighbours[u]:
            if v in cells and v not in dist:
                dist[v] = dist[u] + 1
                queue.append(v)
    return dist


def _connected_with_pins(state: PartitionState, cells: set[int], robot: int) -> bool:
    pins = [u for u in state.whole[robot] if state.pinned(u)]
    if not cells or not pins or not all(p in cells for p in pins):
        return False
    seen = {pins[0]}
    stack = [pins[0]]
    while stack:
        u = stack.pop()
        for v in state.neighbours[u]:
            if v in cells and v not in seen:
                seen.add(v)
                stack.append(v)
    return len(seen) == len(cells)


def _apply(state: PartitionState, big: int, small: int, new_big: set[int]) -> None:
    for u in list(state.whole[big] - new_big):
        state.release(big, u)
        state.claim(small, u)
    for u in list(state.whole[small] & new_big):
        state.release(small, u)
        state.claim(big, u)
