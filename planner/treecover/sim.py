"""Synchronous driver: runs the step rule to the end, checking Lemma 4.1 after every step."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from planner.errors import InfeasiblePlanError, PlannerError
from planner.treecover.rules import split_need
from planner.treecover.splits import cocta_splits, ncocta_splits
from planner.treecover.state import CoverageState
from planner.treecover.step import decide
from planner.treecover.types import Algo, CoverageResult, Splits, Tree


def branching_of(tree: Tree) -> int:
    """N of the tree: its declared branching, else its largest number of children."""
    if tree.branching:
        return tree.branching
    return max(1, int(np.diff(tree.child_start).max())) if tree.n > 1 else 1


def default_splits(tree: Tree, robots: int, algo: Algo) -> Splits:
    """Section 4.2's choice (NCOCTA) or 4.3's (COCTA) for this tree's N and H."""
    choose = ncocta_splits if algo is Algo.NCOCTA else cocta_splits
    return choose(robots, branching_of(tree), tree.height)


def initial_state(tree: Tree, robots: int, algo: Algo,
                  splits: Splits | None = None) -> tuple[Splits, CoverageState]:
    """The splits (given, or the default) and the team at the root before the first step:
    the one set-up of the lockstep runs, the loop clock and the agents' replicas."""
    if robots < 1:
        raise PlannerError(f"need at least one robot (got {robots})")
    if splits is None:
        splits = default_splits(tree, robots, algo)
    state = CoverageState(tree, robots)
    if algo is Algo.COCTA:
        state.need = split_need(state, splits)
    return splits, state


def run_coverage(tree: Tree, robots: int, algo: Algo | str,
                 splits: Splits | None = None) -> CoverageResult:
    """Cover ``tree`` with ``robots`` robots starting at the root until all are back there."""
    algo = Algo(algo)

    def step(state: CoverageState, splits: Splits) -> bool:
        moves = decide(state, algo, splits)
        if moves:
            state.apply(moves)
        return bool(moves)

    return drive(tree, robots, algo, splits, step, "step")


def drive(tree: Tree, robots: int, algo: Algo, splits: Splits | None,
          advance: Callable[[CoverageState, Splits], bool], unit: str) -> CoverageResult:
    """Run ``advance`` (one time unit; False if nobody could move) from the root until the
    team is back there, checking connectivity after every unit (Lemma 4.1)."""
    splits, state = initial_state(tree, robots, algo, splits)
    limit = 4 * tree.n * (tree.height + 2) + 16  # far above any productive run
    connected = True
    explore_time = 0
    occupied: list[int] = []
    while not state.done():
        if state.time >= limit or not advance(state, splits):
            raise InfeasiblePlanError(
                f"{algo.value} stalled at {unit} {state.time} with {robots} robots and splits "
                f"{list(splits.heights)} ({state.remaining} nodes unvisited): too few robots "
                "to keep a trail to the unexplored nodes")
        connected = connected and state.connected()
        occupied.append(len(state.at))
        if state.remaining == 0 and not explore_time:
            explore_time = state.time
    return CoverageResult(algo, robots, splits, state.time, explore_time, 2 * (tree.n - 1),
                          connected, np.array(state.visit_time), tuple(occupied))
