"""Offline MSTC allocations (paper 003): which part of the STC cycle each robot covers.

``allocate`` works in cycle-index space only (n sub-cells, robots at start indices); the plan
builder turns its result into sub-cell paths. Algorithms: ``nb`` non-backtracking (Alg. 1-2),
``bt`` simple backtracking (Alg. 3-4), ``opt`` optimal backtracking (Alg. 5-9, section 4.3).
"""

from __future__ import annotations

from collections.abc import Sequence

from planner.allocation.backtracking import simple_backtracking
from planner.allocation.legs import to_allocations, walk_legs
from planner.allocation.nonbacktracking import non_backtracking
from planner.allocation.optimal import optimal_backtracking
from planner.allocation.ring import check_fuel, make_ring, slot_fuel, slot_speeds
from planner.allocation.types import Cover, Ring, moves
from planner.errors import UnknownAlgorithmError
from planner.types import RobotAllocation

ALGORITHMS = ("nb", "bt", "opt")


def allocate(algo: str, n: int, positions: Sequence[int], *,
             speeds: Sequence[float] | None = None,
             fuel: Sequence[int | None] | None = None) -> tuple[RobotAllocation, ...]:
    """Allocate a cycle of ``n`` sub-cells to robots starting at ``positions`` (robot-id order).

    ``speeds`` (sub-cells per time unit) and ``fuel`` (max moves, None = unlimited) are per
    robot. Only ``opt`` optimises for them; ``nb`` and ``bt`` ignore speeds and raise
    InfeasiblePlanError when their fixed allocation overdraws a robot's fuel.
    """
    if algo not in ALGORITHMS:
        raise UnknownAlgorithmError(
            f"unknown allocation algorithm {algo!r}; choose one of {', '.join(ALGORITHMS)}")
    ring = make_ring(n, positions)
    slot_v = slot_speeds(ring, speeds)
    slot_f = slot_fuel(ring, fuel)
    covers: tuple[Cover, ...]
    if algo == "opt":
        covers = optimal_backtracking(ring, slot_v, slot_f)
    else:
        covers = non_backtracking(ring) if algo == "nb" else simple_backtracking(ring)
        check_fuel(algo, ring, covers, slot_f)
    return to_allocations(ring, covers)


__all__ = ["ALGORITHMS", "Cover", "Ring", "allocate", "make_ring", "moves", "walk_legs"]
