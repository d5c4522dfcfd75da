"""From covers in slot order to RobotAllocation walks in robot-id order."""

from __future__ import annotations

from collections.abc import Sequence

from planner.allocation.types import Cover, Ring
from planner.types import Direction, Leg, RobotAllocation


def walk_legs(forward: int, backward: int) -> tuple[Leg, ...]:
    """The walk covering both sides: the shorter side out, then one run back across the start.

    A backtracking walk is two legs, ``short`` one way and ``short + long`` the other, so every
    leg boundary is a turn-around; ties go CCW first.
    """
    if forward == 0 and backward == 0:
        return ()
    if backward == 0:
        return (Leg(Direction.CCW, forward),)
    if forward == 0:
        return (Leg(Direction.CW, backward),)
    if forward <= backward:
        return (Leg(Direction.CCW, forward), Leg(Direction.CW, forward + backward))
    return (Leg(Direction.CW, backward), Leg(Direction.CCW, backward + forward))


def to_allocations(ring: Ring, covers: Sequence[Cover]) -> tuple[RobotAllocation, ...]:
    """RobotAllocation per robot, in robot-id order."""
    by_robot: dict[int, RobotAllocation] = {}
    for slot, cover in enumerate(covers):
        robot = ring.order[slot]
        by_robot[robot] = RobotAllocation(
            robot=robot, start_index=ring.starts[slot], forward=cover.forward,
            backward=cover.backward, legs=walk_legs(cover.forward, cover.backward))
    return tuple(by_robot[robot] for robot in range(ring.k))
