"""Paper 003 experiments (Fig. 4 and Fig. 5): NB, BT and optimal MSTC makespans.

One trial = one seeded instance (random spanning tree, random or based robot starts) measured
with all three allocations on the same cycle, so the algorithms are compared side by side.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from planner.allocation import ALGORITHMS, allocate
from planner.cycle import stc_cycle
from planner.experiments.instances import based_sub_cells, random_sub_cells
from planner.trees import build_tree
from planner.types import BoolArray

ALGOS = ALGORITHMS  # the paper's three allocations, in its order: nb, bt, opt


@dataclass(frozen=True)
class Trial:
    obstacles: int
    k: int
    bases: int
    trial: int
    n: int
    makespans: tuple[int, int, int]  # nb, bt, opt


def run_trial(cells: BoolArray, k: int, bases: int, seed: int) -> tuple[int, int, int]:
    """Makespans (nb, bt, opt) of one instance: a Wilson random tree and seeded starts."""
    rng = np.random.default_rng(seed)
    tree = build_tree(cells, "random", seed=int(rng.integers(2**31)))
    cycle = stc_cycle(tree)
    starts = (random_sub_cells(cells, k, rng) if bases >= k
              else based_sub_cells(cells, k, bases, rng))
    positions = [cycle.position(s) for s in starts]
    spans = []
    for algo in ALGOS:
        allocations = allocate(algo, cycle.n, positions)
        spans.append(max(a.steps for a in allocations))
    return (spans[0], spans[1], spans[2])


def analytic_curves(n: int, k: int) -> dict[str, float]:
    """The papers' analytic best and worst cases, in moves (see docs/allocation.md)."""
    return {
        "best": float(-(-n // k) - 1),
        "nb_worst": float(n - k),
        "bt_worst": float(np.ceil(2 * n / 3 - 1)) if k == 2 else n / 2 - 1,
    }
