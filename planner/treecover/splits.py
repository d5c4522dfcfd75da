"""Split heights for NCOCTA / COCTA (paper 001, section 4.2) and NCOCTA's closed forms.

All split sets chosen here are consecutive, h_i = h_m + m - i, the case the paper analyses.
The paper's Eq. (1) rounds log_N(m) down: that is the only reading under which both of its
worked numbers hold (16 robots on a 3-ary tree give m = 1; 58 robots give m = 2).
"""

from __future__ import annotations

from planner.treecover.types import Splits


def consecutive(hm: int, m: int) -> Splits:
    """The splits h_1 = h_m + m - 1 > ... > h_m."""
    return Splits(tuple(range(hm + m - 1, hm - 1, -1)))


def robots_needed(branching: int, splits: Splits) -> int:
    """1 + N h_1 + sum_{i>=2} (N^i - N^{i-1}) h_i: a trail from the root to every leaf."""
    if not splits.heights:
        return 1
    n = branching
    h = splits.heights
    return 1 + n * h[0] + sum((n ** i - n ** (i - 1)) * h[i - 1] for i in range(2, len(h) + 1))


def _floor_log(base: int, value: int) -> int:
    if base < 2:
        raise ValueError("logarithm base must be at least 2")
    power, result = base, 0
    while power <= value:
        power, result = power * base, result + 1
    return result


def min_hm(m: int, branching: int) -> int:
    """The smallest h_m of the paper's rule: m + floor(log_N m) + 4."""
    return m + _floor_log(branching, m) + 4


def paper_m(robots: int, branching: int) -> int:
    """The largest m with 1 + N^m (floor(log_N m) + m + 4) + (N^m - N)/(N - 1) <= k; 0 if
    not even m = 1 fits (always 0 for N < 2: a path has nothing to split)."""
    if branching < 2:
        return 0
    m = 0
    while robots_needed(branching, consecutive(min_hm(m + 1, branching), m + 1)) <= robots:
        m += 1
    return m


def _largest_hm(robots: int, branching: int, m: int, height: int) -> int:
    hm = 0
    while hm + m <= height and robots_needed(branching, consecutive(hm + 1, m)) <= robots:
        hm += 1
    return hm


def ncocta_time(branching: int, height: int, splits: Splits) -> int:
    """Steps NCOCTA needs on a perfect tree when every split gets enough robots.

    A split at h_m is finished h_m + (N^h_m - 1)/(N - 1) steps after its team arrives
    (Lemma 4.3); a split at h_i with gap d = h_i - h_{i+1} takes 2 (N^d - 1)/(N - 1) steps of
    walking plus N^(d-1) times the split below; the top is a depth-first walk down to h_1.
    """
    n = branching

    def nodes(levels: int) -> int:  # nodes of a perfect tree with this many levels
        return sum(n ** i for i in range(levels))

    if not splits.heights:
        return 2 * (nodes(height + 1) - 1)
    h = splits.heights
    time = nodes(h[-1]) + h[-1]
    for upper, lower in zip(h[-2::-1], h[:0:-1], strict=True):
        gap = upper - lower
        time = 2 * nodes(gap) + n ** (gap - 1) * time
    top = height - h[0]
    return 2 * (nodes(top + 1) - 1) + n ** top * time


def best_splits(robots: int, branching: int, height: int) -> Splits:
    """Consecutive splits minimising :func:`ncocta_time` among those the team can afford."""
    best = Splits(())
    best_time = ncocta_time(branching, height, best)
    for m in range(1, height + 1):
        hm = _largest_hm(robots, branching, m, height)
        if hm < 1:
            continue
        candidate = consecutive(hm, m)
        time = ncocta_time(branching, height, candidate)
        if time < best_time:
            best, best_time = candidate, time
    return best


def ncocta_splits(robots: int, branching: int, height: int) -> Splits:
    """Section 4.2: the paper's m, then the largest h_m the robots afford (a larger h_m only
    raises the speedup, Lemma 4.4). Where the tree is too low for that rule, or the team too
    small for m = 1 with h_m = 5, fall back to :func:`best_splits`."""
    m = paper_m(robots, branching)
    if m >= 1 and min_hm(m, branching) + m - 1 <= height:
        return consecutive(_largest_hm(robots, branching, m, height), m)
    return best_splits(robots, branching, height)


def cocta_splits(robots: int, branching: int, height: int) -> Splits:
    """Section 4.3: the same m, the minimal h_m; the spare robots drip between subtrees."""
    m = paper_m(robots, branching)
    if m >= 1 and min_hm(m, branching) + m - 1 <= height:
        return consecutive(min_hm(m, branching), m)
    return ncocta_splits(robots, branching, height)


def guaranteed_speedup(branching: int, m: int) -> int:
    """SF(NCOCTA) > 2 N^m - 1 (Lemma 4.5), the figure the paper quotes for its example."""
    return 2 * branching ** m - 1


def lemma44_bound(branching: int, splits: Splits) -> float:
    """Lemma 4.4's lower bound 2 N^(h_m+m) / (N^h_m + 1 + (N - 1)(h_m + 2m))."""
    n, m, hm = branching, splits.m, splits.hm
    return 2 * n ** (hm + m) / (n ** hm + 1 + (n - 1) * (hm + 2 * m))
