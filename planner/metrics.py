"""Plan metrics: makespan, lower bound, coverage, redundancy, turns and turn-aware time.

The time model is TMSTC*'s eq. 8 (paper 002): a robot stops at every twist (start, end and
each 90 degree turn), turns on the spot at ``omega`` and drives each straight run from rest
with acceleration ``accel`` up to ``v_max``. See docs/trees-and-metrics.md for the formula,
the presets' sources and the two places where we read the printed equation differently.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from itertools import pairwise

import numpy as np

from planner.types import BoolArray, Plan, SubCell


@dataclass(frozen=True)
class KinematicParams:
    """Robot kinematics for path_time: tool width (m), v_max (m/s), omega (rad/s), accel (m/s^2).

    ``decelerate`` False is eq. 8 as printed (accelerate from rest, stop at the twist with no
    braking phase); True adds a symmetric braking phase (rest-to-rest triangular/trapezoid
    profile, as simhw's RV-400 model does).
    """

    name: str
    tool_width: float
    v_max: float
    omega: float
    accel: float
    decelerate: bool = False

    def __post_init__(self) -> None:
        for field_name in ("tool_width", "v_max", "omega", "accel"):
            value = getattr(self, field_name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"KinematicParams.{field_name} must be positive, got {value}")

    @property
    def quarter_turn_time(self) -> float:
        """Seconds for one 90 degree turn on the spot at ``omega``."""
        return (math.pi / 2) / self.omega

    def run_time(self, distance: float) -> float:
        """Seconds to drive ``distance`` metres straight, starting (and ending) at rest."""
        if distance <= 0:
            return 0.0
        a, v = self.accel, self.v_max
        if self.decelerate:
            if distance <= v * v / a:
                return 2.0 * math.sqrt(distance / a)
            return distance / v + v / a
        if distance <= v * v / (2 * a):
            return math.sqrt(2 * distance / a)
        return distance / v + v / (2 * a)


# TMSTC* Table I (TurtleBot Kobuki in Gazebo).
KOBUKI = KinematicParams(name="kobuki", tool_width=0.5, v_max=0.5, omega=0.8, accel=0.6)
# RV-400 estimate: the numbers of simhw/kinematics.py (no manufacturer data was found), with
# the same rest-to-rest braking that simhw simulates.
RV400 = KinematicParams(name="rv400", tool_width=0.4, v_max=0.3, omega=1.0, accel=0.5,
                        decelerate=True)
PRESETS = {p.name: p for p in (KOBUKI, RV400)}


@dataclass(frozen=True)
class PlanMetrics:
    """Summary of one plan for the CLI and benchmarks (moves, turns and seconds per robot)."""

    algo: str
    n: int
    k: int
    makespan: int
    lower_bound: int
    steps: tuple[int, ...]
    turns: tuple[int, ...]
    times: tuple[float, ...]
    redundancy: int

    @property
    def makespan_time(self) -> float:
        return max(self.times, default=0.0)

    @property
    def ratio(self) -> float:
        """Makespan over the lower bound (1.0 is optimal; inf when the bound is 0)."""
        if self.lower_bound <= 0:
            return 1.0 if self.makespan <= 0 else math.inf
        return self.makespan / self.lower_bound


def lower_bound(n: int, k: int) -> int:
    """ceil(n / k) - 1: some robot covers at least ceil(n / k) sub-cells, its start included."""
    if k <= 0 or n <= 0:
        raise ValueError(f"lower_bound needs n > 0 and k > 0, got n={n}, k={k}")
    return -(-n // k) - 1


def makespan(plan: Plan) -> int:
    """The largest number of moves of any robot."""
    return plan.makespan


def per_robot_moves(plan: Plan) -> tuple[int, ...]:
    return tuple(rp.steps for rp in plan.robots)


def coverage(paths: Sequence[Sequence[SubCell]], area_sub_cells: BoolArray) -> float:
    """Fraction of the True sub-cells of ``area_sub_cells`` visited by some path (1.0 if none)."""
    want = np.asarray(area_sub_cells, dtype=bool)
    total = int(want.sum())
    if total == 0:
        return 1.0
    seen = np.zeros(want.shape, dtype=bool)
    h, w = want.shape
    for path in paths:
        for r, c in path:
            if 0 <= r < h and 0 <= c < w:
                seen[r, c] = True
    return float((seen & want).sum()) / total


def revisits_per_robot(paths: Sequence[Sequence[SubCell]]) -> tuple[int, ...]:
    """Per robot, its arrivals at sub-cells already visited (by anyone) at that time.

    Paths run in lockstep (``path[t]`` at time t); within one time step lower robot ids count
    as first. The sum over robots equals ``redundancy(paths)``.
    """
    seen: set[SubCell] = set()
    out = [0] * len(paths)
    for t in range(max((len(p) for p in paths), default=0)):
        for i, path in enumerate(paths):
            if t < len(path):
                s = (int(path[t][0]), int(path[t][1]))
                if s in seen:
                    out[i] += 1
                seen.add(s)
    return tuple(out)


def redundancy(paths: Sequence[Sequence[SubCell]]) -> int:
    """Visits beyond the first, summed over sub-cells (0 for a non-redundant plan)."""
    total = sum(len(p) for p in paths)
    distinct = {(int(r), int(c)) for p in paths for r, c in p}
    return total - len(distinct)


def _headings(path: Sequence[SubCell]) -> list[tuple[int, int]]:
    """Unit step vectors of the moves, waits (repeated sub-cells) dropped."""
    arr = np.asarray(path, dtype=np.int64).reshape(-1, 2)
    steps = np.diff(arr, axis=0)
    steps = steps[np.abs(steps).sum(axis=1) > 0]
    return [(int(a), int(b)) for a, b in steps]


def _quarter_turns(a: tuple[int, int], b: tuple[int, int]) -> int:
    if a == b:
        return 0
    if a == (-b[0], -b[1]):
        return 2
    return 1


def count_turns(path: Sequence[SubCell]) -> int:
    """Quarter turns along the path: a 90 degree heading change is 1, a 180 degree reversal 2.

    Waits (a repeated sub-cell) are not moves and do not change the heading. Raises
    ValueError on a step that is not 4-adjacent (its heading is undefined).
    """
    heads = _headings(path)
    for h in heads:
        if abs(h[0]) + abs(h[1]) != 1:
            raise ValueError(f"step {h} is not a 4-adjacent move; turns are undefined")
    return sum(_quarter_turns(a, b) for a, b in pairwise(heads))


def straight_runs(path: Sequence[SubCell]) -> list[int]:
    """Lengths (in moves) of the maximal straight runs between twists."""
    runs: list[int] = []
    previous: tuple[int, int] | None = None
    for h in _headings(path):
        if h == previous:
            runs[-1] += 1
        else:
            runs.append(1)
        previous = h
    return runs


def path_time(path: Sequence[SubCell], params: KinematicParams = KOBUKI) -> float:
    """Seconds to drive ``path`` under TMSTC* eq. 8: sum of run times plus turn times.

    Each straight run of m moves is m * tool_width metres from rest; each quarter turn costs
    (pi / 2) / omega (a reversal two of them).
    """
    runs = straight_runs(path)
    drive = sum(params.run_time(m * params.tool_width) for m in runs)
    return drive + count_turns(path) * params.quarter_turn_time


def plan_metrics(plan: Plan, params: KinematicParams = KOBUKI) -> PlanMetrics:
    """Moves, turns and eq. 8 seconds of every robot of ``plan``."""
    paths = [rp.path for rp in plan.robots]
    return PlanMetrics(
        algo=plan.algo,
        n=plan.n,
        k=plan.k,
        makespan=plan.makespan,
        lower_bound=lower_bound(plan.n, plan.k),
        steps=per_robot_moves(plan),
        turns=tuple(count_turns(p) for p in paths),
        times=tuple(path_time(p, params) for p in paths),
        redundancy=redundancy(paths),
    )
