"""Helpers shared by the NCOCTA and COCTA node rules."""

from __future__ import annotations

from planner.treecover.state import CoverageState
from planner.treecover.types import Move, Splits


def unfinished_children(state: CoverageState, v: int) -> list[int]:
    """Children whose subtree still has unexplored nodes, those already holding robots first
    (a team keeps feeding the branch it works on before opening a new one)."""
    kids = [u for u in state.children[v] if state.unexplored[u] > 0]
    sub = state.sub
    return [u for u in kids if sub[u]] + [u for u in kids if not sub[u]]


def split_evenly(count: int, have: list[int], caps: list[int] | None) -> list[int]:
    """Deal ``count`` robots one at a time to the target holding fewest (``have`` plus dealt),
    never above a target's cap: robots that trickle in still even out the teams."""
    shares = [0] * len(have)
    for _ in range(count):
        open_ = [i for i in range(len(have)) if caps is None or shares[i] < caps[i]]
        if not open_:
            break
        i = min(open_, key=lambda j: have[j] + shares[j])
        shares[i] += 1
    return shares


def fill_in_order(count: int, caps: list[int]) -> list[int]:
    """Give each target in turn as many robots as it can take."""
    shares = []
    for cap in caps:
        share = min(cap, count)
        shares.append(share)
        count -= share
    return shares


def climb_leaving_one(state: CoverageState, v: int, below: int) -> int:
    """How many robots of v climb when all go up but one (unless one climbs in from below)."""
    return state.at[v] if below else state.at[v] - 1


def moves_down(v: int, kids: list[int], shares: list[int]) -> list[Move]:
    return [Move(v, u, s) for u, s in zip(kids, shares, strict=True) if s]


def split_need(state: CoverageState, splits: Splits) -> list[int]:
    """Robots each subtree needs to be covered without stalling under these splits: a split
    node keeps one and feeds every child; any other node keeps one and feeds one child at a
    time. Below h_1 of a perfect tree this is the paper's 1 + N h_1 + sum (N^i - N^(i-1)) h_i;
    above h_1 it counts a trail the whole team, walking together, does not leave."""
    split_levels = set(splits.heights)
    need = [1] * len(state.parent)
    for v in range(len(state.parent) - 1, -1, -1):  # children come after parents
        kids = [need[u] for u in state.children[v]]
        if not kids:
            continue
        level = state.level[v]
        need[v] = 1 + (sum(kids) if level in split_levels else max(kids))
    return need
