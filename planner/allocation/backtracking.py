"""Simple backtracking MSTC (paper 003, Alg. 3-4), with the k = 2 case the paper leaves out.

Robots keep their non-backtracking sections unless one section is longer than half the cycle.
Then the two robots around that long gap share it, and one of them first gets help from its
nearer neighbour, who backtracks over the half of their common gap (Fig. 3). Slot names follow
Alg. 3: h owns the long gap, i = h+1, j = i+1, f = j+1 (f = h when k = 3).

The paper's end points of the shared long gap are replaced by an exact balance (``balance``):
the meeting point where the later of the two robots finishes earliest. See docs/allocation.md
for the index-arithmetic fixes this amounts to.
"""

from __future__ import annotations

from collections.abc import Callable

from planner.allocation.nonbacktracking import non_backtracking
from planner.allocation.types import Cover, Ring, moves


def balance(gap: int, cost_a: Callable[[int], int], cost_b: Callable[[int], int]) -> int:
    """The share x of ``gap`` for robot A (B takes gap - x) minimising the later finish.

    ``cost_a(x)`` and ``cost_b(y)`` must be non-decreasing; binary search finds the first x at
    which A is no faster than B, and the optimum is there or one step before.
    """
    lo, hi = 0, gap
    while lo < hi:
        mid = (lo + hi) // 2
        if cost_a(mid) >= cost_b(gap - mid):
            hi = mid
        else:
            lo = mid + 1
    if lo > 0 and max(cost_a(lo - 1), cost_b(gap - lo + 1)) < max(cost_a(lo), cost_b(gap - lo)):
        return lo - 1
    return lo


def simple_backtracking(ring: Ring) -> tuple[Cover, ...]:
    """Alg. 3's re-division of sections for any k (k = 2: see ``two_robots``)."""
    if ring.k == 1:
        return non_backtracking(ring)
    if ring.k == 2:
        return two_robots(ring)
    long = [h for h, g in enumerate(ring.gaps) if 2 * (g + 1) > ring.n]
    if not long:
        return non_backtracking(ring)
    return _share_long_section(ring, long[0])


def two_robots(ring: Ring) -> tuple[Cover, ...]:
    """k = 2: the robot with the shorter gap covers it, returns, and helps on the longer one.

    This is the behaviour of Theorem 7's proof (case 1), used whenever it beats the
    non-backtracking split. Because a robot walks its shorter side first, it helps as soon as
    the long gap exceeds the short one by more than two sub-cells, not only below n/3 as in
    the proof; the worst case stays within ceil(2n/3 - 1) (measured: about 3(n - 2)/5).
    """
    s = 0 if ring.gaps[0] <= ring.gaps[1] else 1
    short, long = ring.gaps[s], ring.gaps[1 - s]
    # the long gap lies behind the short-gap robot (slot s) and ahead of the other one
    x = balance(long, lambda b: moves(short, b), lambda a: a)
    covers = [Cover(0, 0), Cover(0, 0)]
    covers[s] = Cover(forward=short, backward=x)
    covers[1 - s] = Cover(forward=long - x, backward=0)
    if max(c.moves for c in covers) < long:
        return tuple(covers)
    return non_backtracking(ring)


def _share_long_section(ring: Ring, h: int) -> tuple[Cover, ...]:
    k, g = ring.k, ring.gaps
    i, j, f = (h + 1) % k, (h + 2) % k, (h + 3) % k
    covers = list(non_backtracking(ring))
    if g[i] < g[j]:
        # Alg. 3 lines 9-16: R_i and R_j halve gap i; R_i then helps R_h on the long gap.
        forward_i = g[i] // 2
        covers[j] = Cover(forward=g[j], backward=g[i] - forward_i)
        x = balance(g[h], lambda a: a, lambda b: moves(forward_i, b))
        covers[h] = Cover(forward=x, backward=covers[h].backward)
        covers[i] = Cover(forward=forward_i, backward=g[h] - x)
        return tuple(covers)
    # Alg. 3 lines 17-34: R_j and R_f halve gap j; R_j then covers all of gap i, so R_i is
    # free to walk CW only and share the long gap with R_h.
    forward_j = g[j] // 2
    backward_f = g[j] - forward_j
    covers[j] = Cover(forward=forward_j, backward=g[i])
    if f == h:  # k = 3 (lines 20-26): R_h both helps R_j and shares the long gap with R_i
        x = balance(g[h], lambda a: moves(a, backward_f), lambda b: b)
        covers[h] = Cover(forward=x, backward=backward_f)
    else:
        covers[f] = Cover(forward=g[f], backward=backward_f)
        x = balance(g[h], lambda a: a, lambda b: b)
        covers[h] = Cover(forward=x, backward=covers[h].backward)
    covers[i] = Cover(forward=0, backward=g[h] - x)
    return tuple(covers)
