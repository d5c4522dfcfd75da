"""Value types of the allocation algorithms, in cycle-index space.

Robots are handled in *slot* order: slot 0 is the robot with the smallest start index, and
slots increase counter-clockwise. Gap ``gaps[j]`` is the number of sub-cells strictly between
slot j and slot j + 1 (cyclically); the gaps add up to n - k.
"""

from __future__ import annotations

from dataclasses import dataclass


def moves(forward: int, backward: int) -> int:
    """Moves of a robot covering ``forward`` and ``backward``: the shorter side is walked twice."""
    return forward + backward + min(forward, backward)


@dataclass(frozen=True)
class Ring:
    """Robots on a cycle of ``n`` sub-cells, sorted counter-clockwise into slots."""

    n: int
    order: tuple[int, ...]
    starts: tuple[int, ...]
    gaps: tuple[int, ...]

    @property
    def k(self) -> int:
        return len(self.order)


@dataclass(frozen=True)
class Cover:
    """What one slot's robot covers: ``forward`` sub-cells CCW and ``backward`` CW of its start."""

    forward: int
    backward: int

    @property
    def moves(self) -> int:
        return moves(self.forward, self.backward)
