"""Input validation and the slot view of robots on a cycle, shared by every allocator."""

from __future__ import annotations

import math
from collections.abc import Sequence

from planner.allocation.types import Cover, Ring
from planner.errors import InfeasiblePlanError, RobotParameterError, RobotPlacementError


def make_ring(n: int, positions: Sequence[int]) -> Ring:
    """Sort the robots counter-clockwise and measure the gaps between neighbours."""
    k = len(positions)
    if k == 0:
        raise RobotPlacementError("no robots given: allocation needs at least one robot")
    if n < k:
        raise RobotPlacementError(
            f"{k} robots cannot start on distinct sub-cells of a cycle of only {n}")
    seen: dict[int, int] = {}
    for robot, p in enumerate(positions):
        if not 0 <= p < n:
            raise RobotPlacementError(
                f"robot {robot} starts at cycle index {p}, outside 0..{n - 1}")
        if p in seen:
            raise RobotPlacementError(
                f"robots {seen[p]} and {robot} both start at cycle index {p}")
        seen[p] = robot
    order = tuple(sorted(range(k), key=lambda robot: positions[robot]))
    starts = tuple(int(positions[robot]) for robot in order)
    gaps = tuple((starts[(j + 1) % k] - starts[j] - 1) % n if k > 1 else n - 1
                 for j in range(k))
    return Ring(n=n, order=order, starts=starts, gaps=gaps)


def slot_speeds(ring: Ring, speeds: Sequence[float] | None) -> list[float]:
    """Speeds in slot order (1.0 each when not given), validated."""
    if speeds is None:
        return [1.0] * ring.k
    if len(speeds) != ring.k:
        raise RobotParameterError(f"got {len(speeds)} speeds for {ring.k} robots")
    for robot, s in enumerate(speeds):
        if not (math.isfinite(s) and s > 0):
            raise RobotParameterError(
                f"robot {robot} has speed {s}; speeds must be positive and finite")
    return [float(speeds[robot]) for robot in ring.order]


def slot_fuel(ring: Ring, fuel: Sequence[int | None] | None) -> list[int | None]:
    """Fuel limits (moves) in slot order, None meaning unlimited, validated."""
    if fuel is None:
        return [None] * ring.k
    if len(fuel) != ring.k:
        raise RobotParameterError(f"got {len(fuel)} fuel limits for {ring.k} robots")
    for robot, f in enumerate(fuel):
        if f is not None and f < 0:
            raise RobotParameterError(f"robot {robot} has fuel {f}; fuel must be >= 0 moves")
    return [fuel[robot] for robot in ring.order]


def check_fuel(algo: str, ring: Ring, covers: Sequence[Cover],
               fuel: Sequence[int | None]) -> None:
    """Raise InfeasiblePlanError when a fixed (fuel-blind) allocation overdraws a robot."""
    for slot, (cover, limit) in enumerate(zip(covers, fuel, strict=True)):
        if limit is not None and cover.moves > limit:
            raise InfeasiblePlanError(
                f"{algo} makes robot {ring.order[slot]} walk {cover.moves} moves but its fuel "
                f"is {limit}; only opt takes fuel limits into account")
