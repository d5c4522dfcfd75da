"""Value types of the simulated RV-400 world: poses, outcomes, readings and ground-truth records.

Coordinates, headings and poses are planner.geometry's (headings clockwise from 0 = north).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Literal

# planner.geometry's, re-exported beside the world's own types
from planner.geometry import Heading as Heading
from planner.geometry import Pose as Pose
from planner.geometry import Side as Side
from planner.geometry import SubCell as SubCell

SENSORS: tuple[str, ...] = ("front", "left", "right")


class BodyStatus(Enum):
    ALIVE = "alive"
    FAILED = "failed"
    FROZEN = "frozen"


class SonarMode(Enum):
    """``ALL``: one sense command reads any of the three sonars. ``ONE_AT_A_TIME``: one
    direction per command, the RV-400's limitation (paper 004, section IV)."""

    ALL = "all"
    ONE_AT_A_TIME = "one-at-a-time"


class BumpCause(Enum):
    OBSTACLE = "obstacle"
    EDGE = "edge"
    BODY = "body"


@dataclass(frozen=True)
class Odometry:
    """What the wheel encoders measured during one step (reset after each step)."""

    forward_m: float = 0.0
    turn_rad: float = 0.0


@dataclass(frozen=True)
class WorldConfig:
    """Sensor and odometry options of a world.

    ``sonar_range`` is the farthest sub-cell a sonar reports; ``odometry_noise`` is the standard
    deviation of the odometry error relative to the commanded motion (0.05 = 5 %).
    ``sub_cell_m`` is the tool size D in metres.
    """

    sonar_mode: SonarMode = SonarMode.ALL
    sonar_range: int = 8
    odometry_noise: float = 0.0
    sub_cell_m: float = 0.4

    def __post_init__(self) -> None:
        if self.sonar_range < 1:
            raise ValueError(f"sonar_range must be at least 1, got {self.sonar_range}")
        if not self.odometry_noise >= 0.0:
            raise ValueError(f"odometry_noise must be >= 0, got {self.odometry_noise}")
        if not self.sub_cell_m > 0.0:
            raise ValueError(f"sub_cell_m must be > 0, got {self.sub_cell_m}")


@dataclass(frozen=True)
class BodyView:
    """A snapshot of one body: where it is, whether it can act, where it is moving to."""

    robot: int
    pose: Pose
    status: BodyStatus
    target: SubCell | None = None


@dataclass(frozen=True)
class MoveOutcome:
    """Result of starting a forward step: either the target is reserved or the body bumped."""

    robot: int
    start: Pose
    target: SubCell
    bumped: bool
    cause: BumpCause | None = None


@dataclass(frozen=True)
class StepResult:
    """A finished motion: the pose it ended in and the odometry of that step alone."""

    robot: int
    pose: Pose
    odometry: Odometry
    bumped: bool = False


@dataclass(frozen=True)
class SonarReading:
    """Range per sensor read, in sub-cells from the body's own sub-cell to the first blocked
    sub-cell (1 = the adjacent sub-cell is blocked); None = nothing within the sonar range."""

    ranges: dict[str, int | None] = field(default_factory=dict)


@dataclass(frozen=True)
class CoverRecord:
    """A body entered (or started in) a sub-cell; ``visits`` counts entries so far, all robots."""

    robot: int
    sub: SubCell
    time: float
    visits: int


@dataclass(frozen=True)
class BumpRecord:
    robot: int
    at: SubCell
    into: SubCell
    cause: BumpCause
    time: float


# What happens to a dead robot's body (simhw.dead_bodies): out of the way, or in it.
DeadBodies = Literal["vanish", "block"]
DEAD_BODIES: tuple[DeadBodies, ...] = ("vanish", "block")


@dataclass(frozen=True)
class ServerOptions:
    """How the server runs: sim seconds per wall second (0 = as fast as possible) and how
    long (wall seconds) a command to a frozen body is held before it is answered "frozen"."""

    time_scale: float = 0.0
    frozen_hold_s: float = 600.0
    dead_bodies: DeadBodies = "vanish"
