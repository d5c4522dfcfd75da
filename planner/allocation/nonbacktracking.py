"""Non-backtracking MSTC (paper 003, Alg. 1-2): each robot walks CCW up to the next robot."""

from __future__ import annotations

from planner.allocation.types import Cover, Ring


def non_backtracking(ring: Ring) -> tuple[Cover, ...]:
    """Slot j covers [S_j, S_{j+1}): its whole gap forward, nothing backward."""
    return tuple(Cover(forward=g, backward=0) for g in ring.gaps)
