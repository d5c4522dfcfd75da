"""Optimal backtracking MSTC (paper 003, Alg. 5-9 and section 4.3), by search on the makespan.

Instead of Alg. 6's scan over every robot's every first move (O(n k^2 log n)), the makespan T
is searched and each T is checked greedily (docs/allocation.md has the proof):

* robot i may walk ``B_i = min(floor(T * speed_i), fuel_i)`` moves; with backward cover b it
  reaches at most ``reach(B, b) = B - 2b`` forward if 3b <= B (backward walked twice), else
  ``floor((B - b) / 2)`` (forward walked twice), which is the larger of the two; reach falls
  as b grows and is negative exactly when b > B;
* fixing the backward cover b0 of the chain's first robot forces every later robot: it must
  cover what its predecessor left (b = gap - a of the predecessor) and then reaches as far as
  it can, capped at its own gap (robots never pass). Any allocation has at least these b and
  at most these a, so T is feasible iff the greedy chain closes for some b0;
* the chain starts at the robot with the smallest gap behind it, so b0 takes at most n/k + 1
  values, all checked at once as numpy arrays while looping over the k robots.

Feasibility only changes where some budget steps up, at T = m / speed_i. The search gallops
up from a lower bound (the optimum is usually close to it), then bisects; each feasible check
snaps the upper bound to the real makespan of its allocation, and the search stops when no
budget step lies strictly between the infeasible lower and the achieved upper bound.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import numpy.typing as npt

from planner.allocation.types import Cover, Ring
from planner.errors import InfeasiblePlanError
from planner.types import IntArray

FloatArray = npt.NDArray[np.float64]

# Budgets are floor(T * speed + _EPS): T is often a quotient m / speed that floats round down.
_EPS = 1e-9
# Relative tolerance when comparing two candidate times computed along different routes.
_SAME = 1e-12


def optimal_backtracking(ring: Ring, speeds: Sequence[float],
                         fuel: Sequence[int | None]) -> tuple[Cover, ...]:
    """Covers (slot order) of minimum makespan max(moves / speed) within the fuel limits."""
    k, n = ring.k, ring.n
    if n == k:
        return tuple(Cover(0, 0) for _ in range(k))
    first = min(range(k), key=lambda slot: ring.gaps[slot - 1])
    chain = [(first + t) % k for t in range(k)]
    gaps = [ring.gaps[s] for s in chain]
    speed = np.array([speeds[s] for s in chain], dtype=np.float64)
    # nobody ever needs more than 3(n - 1) moves, so that caps an unlimited tank
    tank = np.array([3 * n if fuel[s] is None else fuel[s] for s in chain], dtype=np.int64)
    if all(f is None for f in fuel):
        start = [Cover(forward=g, backward=0) for g in gaps]  # non-backtracking is feasible
    else:
        b0 = feasible_start(gaps, tank.tolist())
        if b0 is None:
            raise InfeasiblePlanError(_fuel_shortfall(ring, fuel))
        start = chain_covers(gaps, tank.tolist(), b0)
    best = _search(gaps, speed, tank, start)
    out = [Cover(0, 0)] * k
    for t, slot in enumerate(chain):
        out[slot] = best[t]
    return tuple(out)


def _search(gaps: list[int], speed: FloatArray, tank: IntArray,
            best: list[Cover]) -> list[Cover]:
    """Improve the feasible chain ``best`` to the minimum makespan (see the module notes)."""

    def span(covers: list[Cover]) -> float:
        return max(c.moves / s for c, s in zip(covers, speed.tolist(), strict=True))

    hi = span(best)
    lo = _infeasible_below(gaps, speed)
    grow = 1.0 / float(speed.mean())
    galloping = True
    while True:
        step = float(np.min((np.floor(lo * speed + _EPS) + 1) / speed))
        if step >= hi * (1 - _SAME):
            return best
        mid = min(lo + grow, (lo + hi) / 2) if galloping else (lo + hi) / 2
        mid = max(mid, step)
        budget: list[int] = np.minimum(np.floor(mid * speed + _EPS).astype(np.int64),
                                       tank).tolist()
        b0 = feasible_start(gaps, budget)
        if b0 is None:
            lo = mid
            grow *= 2
        else:
            best = chain_covers(gaps, budget, b0)
            hi = span(best)
            galloping = False


def _infeasible_below(gaps: Sequence[int], speed: FloatArray) -> float:
    """A time at and below which no allocation exists.

    All robots together reach at most sum(floor(T * speed)) < T * sum(speed) sub-cells, and a
    gap can only be covered by its two robots; the half-move margin keeps the bound strict.
    """
    total = (sum(gaps) - 0.5) / float(speed.sum())
    pair = speed + np.roll(speed, -1)  # the robots behind and ahead of each gap
    return max(total, float(np.max((np.asarray(gaps) - 0.5) / pair)), 0.0)


def reach(budget: int, backward: int) -> int:
    """Largest forward cover within ``budget`` moves given the backward cover (< 0: b > B)."""
    return max(budget - 2 * backward, (budget - backward) // 2)


def feasible_start(gaps: Sequence[int], budget: Sequence[int]) -> int | None:
    """Smallest backward cover of chain robot 0 that lets the greedy chain close, or None.

    ``gaps[t]`` is the gap ahead of chain robot t; the last one is the gap behind robot 0.
    This is ``reach`` and ``chain_covers`` over an array of every b0 at once.
    """
    last = gaps[-1]
    b0 = np.arange(last + 1, dtype=np.int64)
    low = np.zeros(last + 1, dtype=np.int64)  # smallest reach seen: < 0 means a robot ran dry
    b = b0
    a = b0
    for g, budget_t in zip(gaps, budget, strict=True):
        rest = budget_t - b
        a = np.maximum(rest - b, rest >> 1)  # >> 1 floors like // 2, negatives included
        np.minimum(low, a, out=low)
        np.minimum(a, g, out=a)
        b = g - a
    ok = (low >= 0) & (a + b0 >= last)
    hits = np.flatnonzero(ok)
    return int(hits[0]) if hits.size else None


def chain_covers(gaps: Sequence[int], budget: Sequence[int], b0: int) -> list[Cover]:
    """The greedy chain for one b0, tightened so that neighbours meet without overlap."""
    covers: list[Cover] = []
    b = b0
    for g, budget_t in zip(gaps, budget, strict=True):
        a = min(reach(budget_t, b), g)
        covers.append(Cover(forward=a, backward=b))
        b = g - a
    # the last robot only has to reach where robot 0's backward cover ends
    covers[-1] = Cover(forward=gaps[-1] - b0, backward=covers[-1].backward)
    return covers


def _fuel_shortfall(ring: Ring, fuel: Sequence[int | None]) -> str:
    """Why no allocation fits the fuel: the total, or one gap its two robots cannot bridge."""
    need = ring.n - ring.k
    limited = [f for f in fuel if f is not None]
    if len(limited) == ring.k and sum(limited) < need:
        return (f"fuel limits make coverage impossible: the robots' total fuel is "
                f"{sum(limited)} moves but {need} sub-cells beyond their starts must be reached")
    k = ring.k
    for slot, gap in enumerate(ring.gaps):
        mine, theirs = fuel[slot], fuel[(slot + 1) % k]
        if mine is not None and theirs is not None and mine + theirs < gap:
            return (f"fuel limits make coverage impossible: robots {ring.order[slot]} and "
                    f"{ring.order[(slot + 1) % k]} have {mine} + {theirs} moves of fuel for "
                    f"the {gap} sub-cells between them (robots cannot pass each other)")
    return (f"fuel limits make coverage impossible: the robots' fuel ({sum(limited)} moves "
            f"over {len(limited)} limited robots) cannot reach all {need} sub-cells beyond "
            "their starts, because walking both ways costs extra moves and robots cannot pass")
