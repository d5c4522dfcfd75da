"""Sonar and odometry models of the simulated RV-400.

Sonar: a ray along one of the four headings, reporting how far (in sub-cells) the first blocked
sub-cell is: an obstacle, the map edge, or another body. Odometry: the commanded motion plus
optional Gaussian error from an injected generator, reported per step (the paper reset it after
every step so errors did not accumulate).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

from planner.types import BoolArray
from simhw.types import Heading, Odometry, SubCell

QUARTER_TURN_RAD = math.pi / 2


def sonar_range(blocked: BoolArray, origin: SubCell, heading: Heading,
                max_range: int) -> int | None:
    """Steps from ``origin`` to the first blocked sub-cell along ``heading``, at most
    ``max_range``; None if every sub-cell within range is free. Outside the map is blocked."""
    h, w = blocked.shape
    dr, dc = heading.delta
    r, c = origin
    for step in range(1, max_range + 1):
        rr, cc = r + step * dr, c + step * dc
        if not (0 <= rr < h and 0 <= cc < w) or blocked[rr, cc]:
            return step
    return None


def blocked_mask(free: BoolArray, bodies: Iterable[SubCell]) -> BoolArray:
    """Obstacles plus the sub-cells held by bodies (each as its own blocker)."""
    mask = ~free
    for r, c in bodies:
        mask[r, c] = True
    return mask


def noisy_odometry(forward_m: float, turn_rad: float, sigma: float,
                   rng: np.random.Generator) -> Odometry:
    """The commanded step with relative Gaussian error ``sigma`` (0 gives it exactly)."""
    if sigma == 0.0:
        return Odometry(forward_m=forward_m, turn_rad=turn_rad)
    ef, et = rng.normal(0.0, sigma, size=2)
    return Odometry(forward_m=forward_m * (1.0 + float(ef)),
                    turn_rad=turn_rad * (1.0 + float(et)))
