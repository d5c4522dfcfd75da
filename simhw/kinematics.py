"""How long the RV-400's motion primitives take: a rest-to-rest trapezoidal velocity profile.

Each primitive starts and ends at rest (the ORMSTC robots stop after every step to reset
odometry, paper 004 section IV), so a move of distance d with top speed v and acceleration a
takes ``d / v + v / a`` when it reaches top speed (d >= v^2 / a) and ``2 * sqrt(d / a)``
otherwise (a triangular profile). A 90 degree turn uses the same profile on the angle.
This is the time model of TMSTC* (paper 002, eq. 8) with a symmetric deceleration phase.

The default numbers are estimates, not manufacturer data (none was found): see docs/simhw.md.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Kinematics:
    """Top speed (m/s), linear acceleration (m/s^2), turn rate (rad/s), angular
    acceleration (rad/s^2), sub-cell size D (m) and the time of one sonar reading (s)."""

    speed: float = 0.3
    acceleration: float = 0.5
    turn_rate: float = 1.0
    angular_acceleration: float = 2.0
    sub_cell_m: float = 0.4
    sense_s: float = 0.1

    def __post_init__(self) -> None:
        for name in ("speed", "acceleration", "turn_rate", "angular_acceleration",
                     "sub_cell_m", "sense_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"Kinematics.{name} must be a positive number, got {value}")

    def forward_s(self, sub_cells: int = 1) -> float:
        """Seconds to drive ``sub_cells`` sub-cells straight, from rest to rest."""
        return profile_time(sub_cells * self.sub_cell_m, self.speed, self.acceleration)

    def turn_s(self, quarter_turns: int = 1) -> float:
        """Seconds to turn in place by ``quarter_turns`` x 90 degrees, from rest to rest."""
        return profile_time(abs(quarter_turns) * math.pi / 2, self.turn_rate,
                            self.angular_acceleration)


def profile_time(distance: float, top_speed: float, acceleration: float) -> float:
    """Duration of a rest-to-rest move with a trapezoidal (or triangular) speed profile."""
    if distance <= 0.0:
        return 0.0
    if distance >= top_speed * top_speed / acceleration:
        return distance / top_speed + top_speed / acceleration
    return 2.0 * math.sqrt(distance / acceleration)


RV400 = Kinematics()
