"""COCTA under the readings paper 001's section 4.3 admits (issue 6: the paper's SF 8.6).

    .venv/bin/python benchmarks/bench_cocta_readings.py           # worked example, ~1 s
    .venv/bin/python benchmarks/bench_cocta_readings.py --fig4    # also Fig. 4, both caps, ~1 min

Worked example: a perfect 3-ary tree of height 7, 20 robots (16 for NCOCTA plus four). Each
reading is a cap on a subtree's robots (a CoverageState subclass), a node rule and a split set,
timed by both clocks: one edge per step (``decide_with``) and iterations of the paper's loop
(``iterate``). Prints SF = 2 (|V| - 1) / time; figures recorded in docs/treecover.md.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import dataclass

from planner.treecover.cocta import CoctaRule
from planner.treecover.loop import iterate
from planner.treecover.ncocta import RULE as NCOCTA_RULE
from planner.treecover.rules import climb_leaving_one, split_need
from planner.treecover.sim import default_splits
from planner.treecover.splits import cocta_splits
from planner.treecover.state import CoverageState
from planner.treecover.step import NodeRule, decide_with
from planner.treecover.trees import perfect_tree
from planner.treecover.types import Algo, Splits, Tree

CLOCKS = ("step", "loop")


class UnexploredOrNeedCap(CoverageState):
    """The cap shipped before issue 6: max(unexplored nodes, need)."""

    def useful(self, v: int) -> int:
        if self.unexplored[v] == 0:
            return 0
        return max(self.unexplored[v], self.need[v])


class UnexploredCap(CoverageState):
    """One robot per unexplored node, nothing for the trail."""

    def useful(self, v: int) -> int:
        return self.unexplored[v]


class DripAcrossH1(CoctaRule):
    """Surplus robots climb above h_1 too (Alg. 2's inhabited branch applies everywhere)."""

    def climb(self, state: CoverageState, splits: Splits, v: int, below: int) -> int:
        if state.parent[v] < 0:
            return 0
        if state.unexplored[v] == 0:
            return climb_leaving_one(state, v, below)
        surplus = state.sub[v] - state.useful(v)
        return max(0, min(surplus, climb_leaving_one(state, v, below)))


class SplitOrExploredClimb(CoctaRule):
    """Only split nodes and explored subtrees send robots up; other nodes only go down."""

    def climb(self, state: CoverageState, splits: Splits, v: int, below: int) -> int:
        if state.unexplored[v] and state.level[v] not in splits.heights:
            return 0
        return super().climb(state, splits, v, below)


@dataclass(frozen=True)
class Reading:
    name: str
    state: type[CoverageState]
    rule: NodeRule
    hm6: bool = False  # Lemma 4.5's h_m = m + log_N m + 5 instead of section 4.3's minimum


READINGS = [
    Reading("cap max(unexplored, need), regroup at h_1, h_m 5 (before)", UnexploredOrNeedCap,
            CoctaRule()),
    Reading("  the same, dripping across h_1", UnexploredOrNeedCap, DripAcrossH1()),
    Reading("  the same, h_m 6", UnexploredOrNeedCap, CoctaRule(), hm6=True),
    Reading("cap unexplored nodes only", UnexploredCap, CoctaRule()),
    Reading("cap nodes not finished, regroup at h_1, h_m 5 (kept)", CoverageState, CoctaRule()),
    Reading("  the same, dripping across h_1", CoverageState, DripAcrossH1()),
    Reading("  the same, h_m 6", CoverageState, CoctaRule(), hm6=True),
    Reading("  the same, only split / explored nodes drip up", CoverageState,
            SplitOrExploredClimb()),
]


@dataclass(frozen=True)
class Run:
    time: int  # 0 if the team stalled
    explore_time: int
    connected: bool


def measure(tree: Tree, robots: int, splits: Splits, state_type: type[CoverageState],
            rule: NodeRule, clock: str) -> Run:
    state = state_type(tree, robots)
    state.need = split_need(state, splits)
    limit = 4 * tree.n * (tree.height + 2) + 16
    connected, explore_time = True, 0
    while not state.done():
        if clock == "step":
            moves = decide_with(state, rule, splits)
            if moves:
                state.apply(moves)
            moved = bool(moves)
        else:
            moved = iterate(state, rule, splits)
        if not moved or state.time >= limit:
            return Run(0, 0, connected)
        connected = connected and state.connected()
        if state.remaining == 0 and not explore_time:
            explore_time = state.time
    return Run(state.time, explore_time, connected)


def _sf(tree: Tree, steps: int) -> str:
    return f"{2 * (tree.n - 1) / steps:6.2f}" if steps else " stall"


def worked_example() -> None:
    tree, robots = perfect_tree(3, 7), 20
    base = cocta_splits(robots, 3, 7)
    print(f"3-ary H=7, {robots} robots, COCTA splits {list(base.heights)}; SF per clock")
    print(f"{'reading':60s} {'step':>6s} {'loop':>6s}")
    for reading in READINGS:
        splits = Splits((base.h1 + 1,)) if reading.hm6 else base
        runs = [measure(tree, robots, splits, reading.state, reading.rule, c) for c in CLOCKS]
        assert all(r.connected for r in runs), reading.name
        print(f"{reading.name:60s} " + " ".join(_sf(tree, r.time) for r in runs))
        if "(kept)" in reading.name:
            kept = runs
    print(f"{'  kept, timed to the last new node':60s} "
          + " ".join(_sf(tree, r.explore_time) for r in kept))
    print(f"{'  kept, single-robot time |V| - 1':60s} "
          + " ".join(f"{(tree.n - 1) / r.time:6.2f}" for r in kept))
    for k in (16, 20):
        splits = cocta_splits(k, 3, 7) if k == 16 else Splits((6,))  # NCOCTA's largest h_m
        runs = [measure(tree, k, splits, CoverageState, NCOCTA_RULE, c) for c in CLOCKS]
        print(f"{f'NCOCTA, {k} robots, splits {list(splits.heights)}':60s} "
              + " ".join(_sf(tree, r.time) for r in runs))


def fig4() -> None:
    """Both caps (rule and splits as kept) on every Fig. 4 point, one edge per step."""
    ratios = []
    print("\nFig. 4 points, COCTA, one edge per step: SF before -> kept")
    for n, h in ((2, 15), (3, 8), (4, 8)):
        tree = perfect_tree(n, h)
        for k in range(5, 61, 5):
            splits = default_splits(tree, k, Algo.COCTA)
            before = measure(tree, k, splits, UnexploredOrNeedCap, CoctaRule(), "step")
            kept = measure(tree, k, splits, CoverageState, CoctaRule(), "step")
            ratios.append(before.time / kept.time)
            print(f"{n}-ary H={h} k={k:2d}: {_sf(tree, before.time)} -> {_sf(tree, kept.time)}",
                  flush=True)
    mean = math.exp(sum(map(math.log, ratios)) / len(ratios))
    print(f"geometric mean SF kept / before: {mean:.4f}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--fig4", action="store_true", help="also every Fig. 4 point")
    args = parser.parse_args()
    started = time.perf_counter()
    worked_example()
    if args.fig4:
        fig4()
    print(f"{time.perf_counter() - started:.1f} s")


if __name__ == "__main__":
    main()
